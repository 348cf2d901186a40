#!/usr/bin/env bash
# Requests per second over TCP loopback against the same `mbscope slave` (mmk-2030): `mbscope fuzz` (every
# request generated, framed, judged by the oracle, classified for feedback) against a bare libmodbus client
# loop reading 10 holding registers (bench/slave_load.c, one client), side by side in one run, alternated
# so drift on the machine hits both alike. The fuzzer runs twice: waiting 0 ms where the rules demand
# silence (--silence-wait 0: against this slave nothing late can come), so both measure request turnaround,
# and with its defaults (over Modbus/TCP no wait, a late reply matched to its request by transaction id; the
# wait learnt from the replies only before the connection is dropped after an MBAP length probe), what a
# user gets.
#
#   bench/netfuzz_vs_libmodbus.sh [BUILD_DIR] [SECONDS]     (default build/release, 5 s per measurement)
set -euo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^set /{/^set /d;s/^# \{0,1\}//;p}' "$0"; exit 0 ;; esac
build=${1:-build/release}
seconds=${2:-5}
mbscope="$build/cli/mbscope"
for b in "$mbscope" "$build/bench/slave_load"; do
  [ -x "$b" ] || { echo "netfuzz_vs_libmodbus: $b not built (cmake --build $build)" >&2; exit 2; }
done

out=$(mktemp)
"$mbscope" slave --profile mmk-2030 --listen tcp://127.0.0.1:0 --quiet >"$out" 2>/dev/null &
pid=$!
trap 'kill $pid 2>/dev/null || true; rm -f "$out"' EXIT
for _ in $(seq 100); do [ -s "$out" ] && break; sleep 0.05; done
port=$(head -1 "$out" | sed 's/.*://')
[ -n "$port" ] || { echo "netfuzz_vs_libmodbus: the slave did not start" >&2; exit 2; }

fuzz_rate() {  # extra options of mbscope fuzz
  # Its exit code says whether it found something (a restore refused, say); the rate is what is measured.
  { "$mbscope" fuzz --target "tcp://127.0.0.1:$port" --profile mmk-2030 --duration "${seconds}s" \
      --no-progress "$@" 2>/dev/null || true; } |
    sed -n 's/.*"requests_per_second": \([0-9.]*\).*/\1/p' | awk '{printf "%.0f", $1}'
}
ratio() { awk -v a="$1" -v b="$2" 'BEGIN {printf "%.2fx", a / b}'; }

printf '%-6s %14s %14s %14s %8s %8s\n' round "libmodbus/s" "fuzz, wait 0" "fuzz, default" ratio ratio
for round in 1 2; do
  lib=$("$build/bench/slave_load" 127.0.0.1 "$port" 1 "$seconds" | awk -v s="$seconds" '{printf "%.0f", $1 / s}')
  fast=$(fuzz_rate --silence-wait 0 --timeout 300)
  default=$(fuzz_rate)
  printf '%-6s %14s %14s %14s %8s %8s\n' "$round" "$lib" "$fast" "$default" "$(ratio "$lib" "$fast")" \
    "$(ratio "$lib" "$default")"
done
