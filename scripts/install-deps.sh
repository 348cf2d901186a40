#!/usr/bin/env bash
# Installs the Debian packages mbscope needs, only those missing. Idempotent and quiet when all is there.
set -euo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^set /{/^set /d;s/^# \{0,1\}//;p}' "$0"; exit 0 ;; esac

packages=(
  g++ cmake make pkg-config            # toolchain
  libmodbus-dev                        # peer in tests, serial/TCP plumbing
  libpcap-dev                          # every pcap read and live capture
  nlohmann-json3-dev                   # all JSON
  libgtest-dev                         # all tests
  libcli11-dev                         # command line
  libbenchmark-dev                     # bench/ kernels
  clang libclang-rt-14-dev             # libFuzzer builds (fuzz preset)
  python3 python3-pymodbus python3-serial-asyncio python3-jsonschema socat jpnevulator tshark  # peers, second decoder, schema validator in tests
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

if [ "$(id -u)" -ne 0 ]; then
  echo "mbscope: missing Debian packages: ${missing[*]}" >&2
  echo "mbscope: run this script as root (or: sudo apt-get install ${missing[*]})" >&2
  exit 1
fi
echo "mbscope: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
