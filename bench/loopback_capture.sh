#!/usr/bin/env bash
# The capture issue 4's benchmark asks for: a libmodbus client and a libmodbus server talking Modbus/TCP on
# loopback, recorded by tcpdump. The server is bench/libmodbus_server.c on port 502 (so tshark decodes it
# without a "decode as"; binding it needs root), the clients bench/slave_load.c (FC3 reads of 10 holding
# registers back to back), tcpdump stops after PACKETS packets. Needs tcpdump (Debian package tcpdump).
#
#   bench/loopback_capture.sh [BUILD_DIR] [OUT.pcap] [PACKETS] [CLIENTS]   (default build/release,
#                                                                            loopback.pcap, 400000, 4)
set -euo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^set /{/^set /d;s/^# \{0,1\}//;p}' "$0"; exit 0 ;; esac
build=${1:-build/release}
out=${2:-loopback.pcap}
packets=${3:-400000}
clients=${4:-4}
server="$build/bench/libmodbus_server"
load="$build/bench/slave_load"
for b in "$server" "$load"; do
  [ -x "$b" ] || { echo "loopback_capture: $b not built (cmake --build $build)" >&2; exit 2; }
done
command -v tcpdump >/dev/null || { echo "loopback_capture: tcpdump not installed (apt-get install tcpdump)" >&2; exit 2; }

work=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT

"$server" 502 >"$work/server.out" 2>"$work/server.err" &
pids+=($!)
for _ in $(seq 50); do [ -s "$work/server.out" ] && break; sleep 0.1; done
[ -s "$work/server.out" ] || { echo "loopback_capture: server did not start: $(cat "$work/server.err")" >&2; exit 2; }

# -B: a large kernel buffer, so that loopback at full speed loses nothing; -U: written as captured.
tcpdump -i lo -n -U -Z root -B 262144 -s 0 -c "$packets" -w "$out" 'tcp port 502' 2>"$work/tcpdump.err" &
dump=$!
for _ in $(seq 50); do grep -q listening "$work/tcpdump.err" 2>/dev/null && break; sleep 0.1; done
"$load" 127.0.0.1 502 "$clients" 3600 >"$work/load.out" 2>&1 &
pids+=($!)
wait "$dump"
grep -E 'captured|dropped' "$work/tcpdump.err" >&2 || true
echo "$out: $(capinfos -c -M "$out" 2>/dev/null | awk '/Number of packets/ { print $NF }') packets"
