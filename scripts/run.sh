#!/usr/bin/env bash
# The README's two commands:
#   bash scripts/run.sh demo   install what is missing, build (release), run the main job on bundled data
#   bash scripts/run.sh test   install what is missing, build release and asan, run the whole test suite
#                              under ASan+UBSan, then the fuzz smoke
set -euo pipefail
usage="usage: bash scripts/run.sh demo|test   (demo when none is given)"
case "${1:-demo}" in
  demo|test) ;;
  -h|--help) sed -n '2,/^set /{/^set /d;s/^# \{0,1\}//;p}' "$0"; echo "$usage"; exit 0 ;;
  *) echo "$usage" >&2; exit 2 ;;
esac
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)

bash scripts/install-deps.sh

build() {  # preset [cache options]
  cmake --preset "$@" >/dev/null
  cmake --build --preset "$1" -j "$jobs"
}

# Starts the reference slave on a free port, sends it one Modbus/TCP request through bash's /dev/tcp and
# decodes the answer: the totalizer's reserved registers read 0x55AA, as its manual says (003:574).
slave_demo() {
  local out port pid request reply
  out=$(mktemp)
  ./build/release/cli/mbscope slave --profile cth2265i --listen tcp://127.0.0.1:0 --quiet >"$out" &
  pid=$!
  for _ in $(seq 100); do [ -s "$out" ] && break; sleep 0.05; done
  port=$(sed 's/.*://' "$out")
  rm -f "$out"
  request=$(./build/release/cli/mbscope frame --encode --tcp --unit 1 read-holding 4037 3 |
            sed -n '1s/^tcp  \(.*\)  (.*/\1/p')
  echo "request: $request"
  exec 3<>"/dev/tcp/127.0.0.1/$port"
  printf "$(echo "$request" | sed 's/\([0-9A-Fa-f][0-9A-Fa-f]\) */\\x\1/g')" >&3
  reply=$(timeout 2 head -c 15 <&3 | od -An -v -tx1 | tr -s ' \n' ' ')
  exec 3>&-
  kill "$pid"
  ./build/release/cli/mbscope frame --tcp --direction response $reply
}

# The fuzz targets built through the ClusterFuzzLite contract (.clusterfuzzlite/build.sh) with clang and
# local values, then each run briefly from its seed corpus: fails on a crash, leak, timeout or oracle violation.
# build.sh is run as the image runs it (.clusterfuzzlite/Dockerfile): copied to $SRC/build.sh, from the tree.
fuzz_smoke() {
  local flags="-O1 -g -fno-omit-frame-pointer -fsanitize=address,undefined,fuzzer-no-link -fno-sanitize-recover=all"
  rm -rf build/fuzz-out build/fuzz-src
  mkdir -p build/fuzz-src
  cp .clusterfuzzlite/build.sh build/fuzz-src/build.sh
  CC=clang CXX=clang++ CFLAGS="$flags" CXXFLAGS="$flags" LIB_FUZZING_ENGINE=-fsanitize=fuzzer \
    SRC="$PWD/build/fuzz-src" OUT="$PWD/build/fuzz-out" WORK="$PWD/build" bash -eu build/fuzz-src/build.sh
  bash fuzz/smoke.sh --out build/fuzz-out "${MBSCOPE_FUZZ_SECONDS:-8}"
}

case "${1:-demo}" in
  demo)
    build release >/dev/null
    echo "== mbscope frame: the manuals' worked example frames, decoded field by field"
    ./build/release/cli/mbscope frame --file captures/manual-examples.txt
    echo
    echo "== mbscope decode: a public Modbus/TCP capture (captures/SOURCES.md), every transaction and fault"
    rc=0
    ./build/release/cli/mbscope decode captures/suricata-modbus.pcap || rc=$?
    [ "$rc" -le 1 ]  # 1 means "faults found", which is what this capture is for
    echo
    echo "== mbscope slave: a CTH2265I flow totalizer served on loopback, read with a request built by mbscope frame"
    slave_demo
    ;;
  test)
    # The release build is compiled without the tests (its -O2 warnings are errors too, and the demo runs
    # it) and without the fuzz targets' replay programs (the sanitizer build makes and runs them); the
    # suite runs once, under the sanitizers, which check more than a release run of the same tests
    # (README.md, "Building by hand"). Twice the cores: many tests wait on timers, not the CPU.
    build release -DMBSCOPE_BUILD_TESTS=OFF -DMBSCOPE_BUILD_FUZZ_REPLAYS=OFF
    build asan
    ctest --preset asan -j "$((jobs * 2))"
    fuzz_smoke
    ;;
esac
