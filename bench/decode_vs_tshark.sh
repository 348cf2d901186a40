#!/usr/bin/env bash
# Whole-process decoding speed: `mbscope decode --summary` and `--jsonl` against issue 4's tshark command
# (`tshark -r FILE -T fields -e mbtcp.trans_id -e modbus.func_code`) on the same captures, side by side in
# one run. Captures: the issue's own, a libmodbus client and server on loopback recorded by tcpdump
# (bench/loopback_capture.sh, PACKETS packets; needs root and tcpdump, skipped otherwise); a generated plant
# mix (bench/modbus_pcap_gen.c: 16 clients, FC3/FC4 reads of 1..64 registers, FC6/FC16 writes, exceptions,
# PACKETS/2 transactions); and, when ../shared/captures is there, its largest real capture (ModbusTCP.pcap).
#
# Each command runs ROUNDS times, the three commands alternated so that drift on the machine hits all alike;
# the best wall time of each is kept and the ratios are printed (never a lone absolute time).
#
#   bench/decode_vs_tshark.sh [BUILD_DIR] [PACKETS] [ROUNDS]   (default build/release, 400000, 3)
set -euo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^set /{/^set /d;s/^# \{0,1\}//;p}' "$0"; exit 0 ;; esac
build=${1:-build/release}
packets=${2:-400000}
rounds=${3:-3}
mbscope="$build/cli/mbscope"
gen="$build/bench/modbus_pcap_gen"
for b in "$mbscope" "$gen"; do
  [ -x "$b" ] || { echo "decode_vs_tshark: $b not built (cmake --build $build)" >&2; exit 2; }
done
command -v tshark >/dev/null || { echo "decode_vs_tshark: tshark not installed" >&2; exit 2; }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$gen" "$work/generated.pcap" $((packets / 2))

names=("mbscope decode --summary" "mbscope decode --jsonl" "tshark -T fields (issue 4)")
run() {  # run INDEX FILE: one command, output thrown away
  case $1 in
    0) "$mbscope" decode --summary --no-progress "$2" ;;
    1) "$mbscope" decode --jsonl --no-progress "$2" ;;
    2) tshark -r "$2" -T fields -e mbtcp.trans_id -e modbus.func_code ;;
  esac >/dev/null 2>&1 || true  # findings give mbscope exit code 1
}
seconds() { date +%s.%N; }

bench_file() {  # bench_file FILE LABEL
  local file=$1 label=$2 best=() i r t0 t1
  for i in 0 1 2; do best[i]=999999; done
  for ((r = 0; r < rounds; ++r)); do
    for i in 0 1 2; do
      t0=$(seconds); run "$i" "$file"; t1=$(seconds)
      best[i]=$(awk -v a="${best[i]}" -v b="$(awk -v x="$t0" -v y="$t1" 'BEGIN { print y - x }')" \
                'BEGIN { print (b < a) ? b : a }')
    done
  done
  local packets size
  packets=$(capinfos -c -M "$file" 2>/dev/null | awk '/Number of packets/ { print $NF }')
  size=$(stat -c %s "$file")
  echo "$label: $(basename "$file"), $size bytes, $packets packets, $(nproc) cores, best of $rounds"
  printf '  %-30s %10s %18s\n' command "seconds" "vs mbscope --summary"
  for i in 0 1 2; do
    awk -v n="${names[i]}" -v t="${best[i]}" -v base="${best[0]}" \
      'BEGIN { printf "  %-30s %10.2f %18.2f\n", n, t, t / base }'
  done
  awk -v t="${best[2]}" -v s="${best[0]}" -v j="${best[1]}" \
    'BEGIN { printf "  tshark / mbscope --summary: %.1fx (goal 100x);  tshark / mbscope --jsonl: %.1fx (goal 30x)\n", t / s, t / j }'
}

if [ "$(id -u)" = 0 ] && command -v tcpdump >/dev/null; then
  bash "$(dirname "$0")/loopback_capture.sh" "$build" "$work/loopback.pcap" "$packets" 4 >/dev/null
  bench_file "$work/loopback.pcap" "libmodbus on loopback, tcpdump"
else
  echo "loopback capture skipped: needs root (port 502) and tcpdump" >&2
fi
bench_file "$work/generated.pcap" "generated plant mix"
real="$(dirname "$0")/../../shared/captures/ITI__ICS-Security-Tools/ModbusTCP.pcap"
[ -f "$real" ] && bench_file "$real" "real"
exit 0
