#!/usr/bin/env bash
# The README's two commands:
#   bash scripts/run.sh demo   install what is missing, build (release), run the main job on bundled data
#   bash scripts/run.sh test   install what is missing, build release and asan, run the whole test suite
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)

bash scripts/install-deps.sh

build() {  # preset
  cmake --preset "$1" >/dev/null
  cmake --build --preset "$1" -j "$jobs"
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
    ;;
  test)
    build release
    ctest --preset release -j "$jobs"
    build asan
    ctest --preset asan -j "$jobs"
    ;;
  *)
    echo "usage: bash scripts/run.sh demo|test" >&2
    exit 2
    ;;
esac
