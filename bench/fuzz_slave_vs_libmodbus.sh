#!/usr/bin/env bash
# The slave fuzz targets against the reference point of issue 7's goal, a libmodbus receive-and-reply
# harness built like libmodbus's own (bench/libmodbus_fuzz_server.c), with the same sanitizers, libFuzzer
# flags and time, the three one after the other ROUNDS times. Printed for each: libFuzzer's executions per
# second and, for fuzz_slave, requests per second (an input of fuzz_slave is a sequence of requests; one of
# fuzz_slave_request or of the libmodbus harness is one request), then the ratios.
#
#   bench/fuzz_slave_vs_libmodbus.sh FUZZ_DIR [SECONDS] [ROUNDS]
# FUZZ_DIR holds fuzz_slave, fuzz_slave_request and their dictionaries: build/fuzz/fuzz of the `fuzz` preset, or the $OUT of
# .clusterfuzzlite/build.sh. Needs clang and libmodbus-dev.
set -euo pipefail
cd "$(dirname "$0")/.."
usage="usage: bench/fuzz_slave_vs_libmodbus.sh FUZZ_DIR [SECONDS] [ROUNDS]"
case "${1:-}" in -h|--help) echo "$usage"; exit 0 ;; "") echo "$usage" >&2; exit 2 ;; esac
dir=$(cd "$1" 2>/dev/null && pwd) || { echo "bench/fuzz_slave_vs_libmodbus.sh: no directory $1" >&2; exit 2; }
for f in fuzz_slave fuzz_slave.dict fuzz_slave_request fuzz_slave_request.dict; do
  [ -e "$dir/$f" ] || { echo "bench/fuzz_slave_vs_libmodbus.sh: $dir has no $f" >&2; exit 2; }
done
seconds=${2:-8}
rounds=${3:-2}
work=$(mktemp -d -p /dev/shm 2>/dev/null || mktemp -d)
trap 'rm -rf "$work"' EXIT
export MBSCOPE_PROFILE_PATH="$PWD/profiles"

flags="-O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined,fuzzer -fno-sanitize-recover=all"
# shellcheck disable=SC2086,SC2046
clang $flags $(pkg-config --cflags libmodbus) bench/libmodbus_fuzz_server.c $(pkg-config --libs libmodbus) \
  -lpthread -o "$work/libmodbus_fuzz_server"

# run NAME BINARY CORPUS DICT [MAX_LEN]: writes "exec/s requests" to $work/NAME.result; a target that fails
# stops the script (in the shell itself, not in a process substitution, whose exit went unseen: the script
# printed 0 exec/s and exited 0).
run() {
  rm -rf "$work/corpus" && mkdir -p "$work/corpus" && cp -r "$3/." "$work/corpus/"
  MBSCOPE_FUZZ_STATS=1 "$2" "$work/corpus" -dict="$4" -max_total_time="$seconds" -seed=1 -max_len="${5:-65536}" \
    -print_final_stats=1 >"$work/$1.log" 2>&1 || { echo "$1 failed:" >&2; tail -5 "$work/$1.log" >&2; exit 1; }
  local rate requests
  rate=$(sed -n 's/^stat::average_exec_per_sec: *\([0-9]*\)/\1/p' "$work/$1.log" | tail -1)
  requests=$(sed -n 's/^fuzz_slave: requests handled: \([0-9]*\)/\1/p' "$work/$1.log" | tail -1)
  [ -n "$rate" ] || { echo "$1: no exec/s in its log" >&2; exit 1; }
  echo "$rate ${requests:-}" >"$work/$1.result"
}

echo "fuzz_slave and fuzz_slave_request against a libmodbus receive-and-reply harness, $seconds s each, $(nproc) cores"
# fuzz_slave_request's bound on its input, as the smoke and ClusterFuzzLite read it.
one_max_len=$(sed -n 's/^max_len *= *\([0-9]*\)/\1/p' fuzz/slave_request.options)
for ((r = 1; r <= rounds; ++r)); do
  run slave "$dir/fuzz_slave" corpus/slave "$dir/fuzz_slave.dict"
  run slave_request "$dir/fuzz_slave_request" corpus/slave_request "$dir/fuzz_slave_request.dict" "$one_max_len"
  run libmodbus "$work/libmodbus_fuzz_server" corpus/libmodbus_diff fuzz/modbus_tcp.dict
  read -r ours requests <"$work/slave.result"
  read -r one _ <"$work/slave_request.result"
  read -r theirs _ <"$work/libmodbus.result"
  runs=$(grep -o 'Done [0-9]* runs' "$work/slave.log" | grep -o '[0-9]*' | head -1)
  awk -v o="$ours" -v one="$one" -v t="$theirs" -v q="$requests" -v n="$runs" -v r="$r" 'BEGIN {
    per = (n > 0) ? q / n : 0
    printf "round %d: fuzz_slave %d exec/s (%.1f requests per input, ~%d requests/s); fuzz_slave_request %d exec/s;" \
      " libmodbus harness %d exec/s\n", r, o, per, o * per, one, t
    printf "  exec/s: fuzz_slave / libmodbus = %.2fx, fuzz_slave_request / libmodbus = %.1fx;" \
      "  requests/s: fuzz_slave / libmodbus = %.1fx   (issue 7: 50,000 exec/s, ten times the harness)\n",
      o / t, one / t, o * per / t
  }'
done
