#!/usr/bin/env bash
# Requests per second over TCP loopback against the same `mbscope slave` (mmk-2030): `mbscope fuzz` (every
# request generated, framed, judged by the oracle, classified for feedback) against a bare libmodbus client
# loop reading 10 holding registers (bench/slave_load.c, one client), side by side in one run, alternated
# so drift on the machine hits both alike. The fuzzer waits 0 ms where the rules demand silence
# (--silence-wait 0: against this slave nothing late can come), so both measure request turnaround.
#
#   bench/netfuzz_vs_libmodbus.sh [BUILD_DIR] [SECONDS]     (default build/release, 5 s per measurement)
set -euo pipefail
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

printf '%-6s %16s %16s %8s\n' round "mbscope fuzz/s" "libmodbus/s" ratio
for round in 1 2; do
  lib=$("$build/bench/slave_load" 127.0.0.1 "$port" 1 "$seconds" | awk -v s="$seconds" '{printf "%.0f", $1 / s}')
  # Its exit code says whether it found something (a restore refused, say); the rate is what is measured.
  fuzz=$({ "$mbscope" fuzz --target "tcp://127.0.0.1:$port" --profile mmk-2030 --duration "${seconds}s" \
             --silence-wait 0 --timeout 300 --no-progress 2>/dev/null || true; } |
         sed -n 's/.*"requests_per_second": \([0-9.]*\).*/\1/p' | awk '{printf "%.0f", $1}')
  printf '%-6s %16s %16s %8s\n' "$round" "$fuzz" "$lib" "$(awk -v a="$lib" -v b="$fuzz" 'BEGIN {printf "%.2fx", a / b}')"
done
