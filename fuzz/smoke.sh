#!/usr/bin/env bash
# Fuzz smoke: every target for a bounded time from its seed corpus (a copy: the checked-in corpus is not
# touched), with its dictionary, failing on any crash, leak, timeout or oracle violation. Two targets run at a
# time. Usage: fuzz/smoke.sh [--out] DIR [SECONDS_PER_TARGET], DIR holding fuzz_<name> and fuzz_<name>.dict:
# build/fuzz/fuzz of the `fuzz` preset, or with --out the $OUT of .clusterfuzzlite/build.sh, whose promised
# files are checked first: every target of fuzz/CMakeLists.txt, its dictionary, its seed corpus archive, its
# options where fuzz/ has them, and the profiles. DIR is taken from the working directory.
set -uo pipefail
usage="usage: fuzz/smoke.sh [--out] DIR [SECONDS]"
contract=0
case "${1:-}" in
  -h|--help) echo "$usage"; exit 0 ;;
  --out) contract=1; shift ;;
esac
[ $# -ge 1 ] || { echo "$usage" >&2; exit 2; }
dir=$(cd "$1" 2>/dev/null && pwd) || { echo "fuzz/smoke.sh: no directory $1" >&2; exit 2; }
seconds=${2:-15}
cd "$(dirname "$0")/.."
# A fixed seed: the smoke explores the same inputs on every run (as far as the time allows), so a red CI
# run is a reproducible one. New ground is the continuous fuzzing's job (ClusterFuzzLite, -fork locally).
seed=${MBSCOPE_FUZZ_SEED:-1}
# libFuzzer writes every input that adds coverage to the corpus folder, hundreds a second at first; on a disk
# creating those files took a tenth of the deframers' time (perf: ext4_create under open). The working copy
# is thrown away, so it lives in memory where there is a tmpfs.
work=$(mktemp -d -p /dev/shm 2>/dev/null || mktemp -d)
trap 'rm -rf "$work"' EXIT
export MBSCOPE_PROFILE_PATH="$PWD/profiles"

run_one() {  # target
  local t=$1 corpus="$work/corpus-$1" log="$work/$1.log"
  mkdir -p "$corpus" "$work/artifacts-$t"
  [ -d "corpus/$t" ] && cp -r "corpus/$t/." "$corpus/"
  # A target's own bound on its input and on one run's time, from fuzz/<target>.options as ClusterFuzzLite
  # reads it; else 64 KiB and 10 s.
  local max_len timeout
  max_len=$(sed -n 's/^max_len *= *\([0-9]*\)/\1/p' "fuzz/$t.options" 2>/dev/null)
  timeout=$(sed -n 's/^timeout *= *\([0-9]*\)/\1/p' "fuzz/$t.options" 2>/dev/null)
  "$dir/fuzz_$t" "$corpus" -dict="$dir/fuzz_$t.dict" -max_total_time="$seconds" -timeout="${timeout:-10}" -seed="$seed" \
    -rss_limit_mb=2048 -max_len="${max_len:-65536}" -print_final_stats=1 -artifact_prefix="$work/artifacts-$t/" \
    >"$log" 2>&1
  local rc=$?
  local runs rate
  runs=$(grep -o 'Done [0-9]* runs' "$log" | tail -1)
  # libFuzzer's average over the fuzzing time: what a target prepares once (LLVMFuzzerInitialize: the slave's
  # profiles) is not in it, the first run over the seed corpus is.
  rate=$(sed -n 's/^stat::average_exec_per_sec: *\([0-9]*\)/\1/p' "$log" | tail -1)
  if [ $rc -ne 0 ]; then
    echo "fuzz_$t: FAILED (exit $rc)"
    grep -E 'property violated|ERROR: |SUMMARY|what\(\)' "$log" | head -5
    for a in "$work/artifacts-$t"/*; do
      [ -e "$a" ] || continue
      mkdir -p "fuzz/regressions/$t"
      cp "$a" "fuzz/regressions/$t/"
      echo "  reproducer saved as fuzz/regressions/$t/$(basename "$a") (replay: $dir/fuzz_$t FILE)"
    done
    return 1
  fi
  echo "fuzz_$t: ok (${runs:-no runs recorded} in ${seconds} s, ${rate:-?} exec/s)"
}

targets=$(sed -n 's/^set(MBSCOPE_FUZZ_TARGETS \(.*\))$/\1/p' fuzz/CMakeLists.txt)
missing=0
for t in $targets; do
  for f in "fuzz_$t" "fuzz_$t.dict"; do
    [ -e "$dir/$f" ] || { echo "missing: $dir/$f" >&2; missing=1; }
  done
  # A seed longer than the target's max_len is only its first max_len bytes to libFuzzer: the corpus would
  # claim inputs the fuzzer never runs (fuzz/make_corpus.py writes seeds cut to it).
  bound=$(sed -n 's/^max_len *= *\([0-9]*\)/\1/p' "fuzz/$t.options" 2>/dev/null)
  if [ -n "$bound" ] && [ -d "corpus/$t" ]; then
    long=$(find "corpus/$t" -type f -size +"${bound}"c)
    for f in $long; do
      echo "corpus: $f holds $(wc -c <"$f") bytes, over max_len $bound of fuzz/$t.options" >&2
      missing=1
    done
  fi
  [ $contract -eq 1 ] || continue
  if [ -d "corpus/$t" ] && [ ! -s "$dir/fuzz_${t}_seed_corpus.zip" ]; then
    echo "missing: $dir/fuzz_${t}_seed_corpus.zip" >&2
    missing=1
  fi
  if [ -f "fuzz/$t.options" ] && [ ! -f "$dir/fuzz_$t.options" ]; then
    echo "missing: $dir/fuzz_$t.options" >&2
    missing=1
  fi
done
if [ $contract -eq 1 ] && [ ! -f "$dir/profiles/modbus.json" ]; then
  echo "missing: $dir/profiles (the bundled device profiles)" >&2
  missing=1
fi
[ $missing -eq 0 ] || exit 2
failed=0
set -- $targets
while [ $# -gt 0 ]; do
  run_one "$1" & a=$!
  if [ $# -gt 1 ]; then run_one "$2" & b=$!; else b=; fi
  wait $a || failed=1
  [ -n "$b" ] && { wait $b || failed=1; }
  shift; [ $# -gt 0 ] && shift
done
exit $failed
