#!/bin/bash -eu
# The OSS-Fuzz / ClusterFuzzLite build contract: $CC $CXX $CFLAGS $CXXFLAGS $LIB_FUZZING_ENGINE in, fuzz
# targets in $OUT, each with its seed corpus (fuzz_<name>_seed_corpus.zip), its dictionary (fuzz_<name>.dict)
# and, where it has one, its options (fuzz_<name>.options); and the device profiles beside them
# ($OUT/profiles, where the targets look first after $MBSCOPE_PROFILE_PATH).
# Also run by the project's own test command with local values (scripts/run.sh), so it cannot rot.
# Build type None: the contract's flags alone decide optimisation and debug information (fuzz/README.md).
# The source tree: the one this script sits in (.clusterfuzzlite/build.sh, as the test command runs it), else
# the working directory, where the image's Dockerfile copies the tree and from where OSS-Fuzz runs the script
# copied to $SRC/build.sh (its parent is no source tree).
here=$(cd "$(dirname "$0")/.." && pwd)
if [ -z "${SRC_DIR:-}" ]; then
  if [ -f "$here/CMakeLists.txt" ] && [ -f "$here/.clusterfuzzlite/build.sh" ]; then SRC_DIR=$here; else SRC_DIR=$PWD; fi
fi
[ -f "$SRC_DIR/CMakeLists.txt" ] || { echo "build.sh: no source tree at $SRC_DIR (set SRC_DIR)" >&2; exit 1; }
BUILD=${WORK:-/tmp}/mbscope-fuzz-build

cmake -S "$SRC_DIR" -B "$BUILD" \
  -DCMAKE_BUILD_TYPE=None \
  -DCMAKE_C_COMPILER="$CC" -DCMAKE_CXX_COMPILER="$CXX" \
  -DCMAKE_C_FLAGS="$CFLAGS" -DCMAKE_CXX_FLAGS="$CXXFLAGS" \
  -DMBSCOPE_FUZZ_ENGINE="$LIB_FUZZING_ENGINE" \
  -DMBSCOPE_BUILD_TESTS=OFF -DMBSCOPE_BUILD_BENCH=OFF -DMBSCOPE_WERROR=OFF >/dev/null
cmake --build "$BUILD" --target fuzz_targets -j "$(nproc)"

mkdir -p "$OUT"
for binary in "$BUILD"/fuzz/fuzz_*; do
  name=$(basename "$binary")
  case "$name" in *.dict) continue ;; esac
  cp "$binary" "$OUT/"
  cp "$BUILD/fuzz/$name.dict" "$OUT/"
  target=${name#fuzz_}
  # Per-target libFuzzer options (fuzz/<target>.options: max_len where the input has a natural bound).
  if [ -f "$SRC_DIR/fuzz/$target.options" ]; then cp "$SRC_DIR/fuzz/$target.options" "$OUT/$name.options"; fi
  if [ -d "$SRC_DIR/corpus/$target" ]; then
    (cd "$SRC_DIR/corpus/$target" && python3 -c "
import os, sys, zipfile
with zipfile.ZipFile(sys.argv[1], 'w') as z:
    for f in sorted(os.listdir('.')):
        z.write(f)" "$OUT/${name}_seed_corpus.zip")
  fi
done
rm -rf "$OUT/profiles"
cp -r "$SRC_DIR/profiles" "$OUT/profiles"
