#!/usr/bin/env bash
# Whole-process decoding speed: `mbscope decode` against tshark 4.0 on the same capture, side by side in one
# run. The capture is generated (bench/modbus_pcap_gen.c, through libpcap): TRANSACTIONS Modbus/TCP
# request/response pairs from 16 clients, a plant's mix of FC3/FC4 reads, FC6/FC16 writes and exceptions.
# If ../shared/captures is there, its largest real capture (ModbusTCP.pcap) is timed the same way.
#
# Each command runs ROUNDS times, the four commands alternated so that drift on the machine hits all alike;
# the best wall time of each is kept and the ratios are printed (never a lone absolute time).
#
#   bench/decode_vs_tshark.sh [BUILD_DIR] [TRANSACTIONS] [ROUNDS]   (default build/release, 500000, 3)
set -euo pipefail
build=${1:-build/release}
transactions=${2:-500000}
rounds=${3:-3}
mbscope="$build/cli/mbscope"
gen="$build/bench/modbus_pcap_gen"
for b in "$mbscope" "$gen"; do
  [ -x "$b" ] || { echo "decode_vs_tshark: $b not built (cmake --build $build)" >&2; exit 2; }
done
command -v tshark >/dev/null || { echo "decode_vs_tshark: tshark not installed" >&2; exit 2; }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$gen" "$work/bench.pcap" "$transactions"

fields=(-e frame.number -e mbtcp.trans_id -e mbtcp.unit_id -e modbus.func_code)
names=("mbscope decode --summary" "mbscope decode --jsonl" "tshark -Y modbus" "tshark -Y modbus -T fields")
run() {  # run INDEX FILE: one command, output thrown away
  case $1 in
    0) "$mbscope" decode --summary --no-progress "$2" ;;
    1) "$mbscope" decode --jsonl --no-progress "$2" ;;
    2) tshark -r "$2" -Y modbus ;;
    3) tshark -r "$2" -Y modbus -T fields "${fields[@]}" ;;
  esac >/dev/null 2>&1 || true  # findings give mbscope exit code 1
}
seconds() { date +%s.%N; }

bench_file() {  # bench_file FILE LABEL
  local file=$1 label=$2 best=() i r t0 t1
  for i in 0 1 2 3; do best[i]=999999; done
  for ((r = 0; r < rounds; ++r)); do
    for i in 0 1 2 3; do
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
  for i in 0 1 2 3; do
    awk -v n="${names[i]}" -v t="${best[i]}" -v base="${best[0]}" \
      'BEGIN { printf "  %-30s %10.2f %18.2f\n", n, t, t / base }'
  done
  awk -v a="${best[2]}" -v b="${best[0]}" -v c="${best[3]}" -v d="${best[1]}" \
    'BEGIN { printf "  tshark -Y modbus / mbscope --summary: %.1fx;  tshark -T fields / mbscope --jsonl: %.1fx\n", a / b, c / d }'
}

bench_file "$work/bench.pcap" "generated"
real="$(dirname "$0")/../../shared/captures/ITI__ICS-Security-Tools/ModbusTCP.pcap"
[ -f "$real" ] && bench_file "$real" "real"
exit 0
