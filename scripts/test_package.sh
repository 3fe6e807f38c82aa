#!/usr/bin/env bash
# The installed package on its own: installs BUILD_DIR (default ./build) into a temporary prefix,
# moves the prefix elsewhere, checks that no installed file names the source or build tree,
# builds examples/embed against the moved prefix (find_package(mcslam CONFIG)) and a one-file
# program with `pkg-config --cflags --libs mcslam`, then, with the build tree renamed away,
# runs the example and the installed CLI on a synthetic sequence and compares their poses.
# Usage: scripts/test_package.sh [BUILD_DIR]   (scripts/test.sh runs it after ctest)
set -euo pipefail
cd "$(dirname "$0")/.."
src=$(pwd -P)
build=$(cd "${1:-build}" && pwd -P)
[ -x "$build/mcslam" ] || { echo "test_package: $build/mcslam not found; build first" >&2; exit 1; }
jobs=$(nproc)

work=$(mktemp -d /tmp/mcslam-package.XXXXXX)
hidden="$build.hidden-by-test-package"
restore() {
  if [ -d "$hidden" ] && [ ! -e "$build" ]; then mv "$hidden" "$build"; fi
  rm -rf "$work"
}
trap restore EXIT
fail() { echo "test_package: FAILED: $*" >&2; exit 1; }

echo "test_package: installing into $work/staging, then moving it to $work/prefix"
cmake --install "$build" --prefix "$work/staging" > "$work/install.log"
mv "$work/staging" "$work/prefix"
prefix="$work/prefix"
for f in bin/mcslam share/mcslam/orb_vocabulary.bin include/mcslam/mcslam.hpp \
         include/mcslam/version.hpp lib/cmake/mcslam/mcslamConfig.cmake \
         lib/cmake/mcslam/mcslamConfigVersion.cmake lib/pkgconfig/mcslam.pc \
         lib/libmcslam_core.a share/doc/mcslam/LICENSE; do
  [ -e "$prefix/$f" ] || fail "$f was not installed"
done
# Nothing installed may name the source or the build tree (text or binary).
if grep -rlF -e "$src/" -e "$build" "$prefix"; then fail "the files above name $src or $build"; fi

# The CLI and the example against the prefix only, with the build tree out of the way.
synth="$work/synth"
"$build/mcslam" synth --output "$synth" --frames 30 -q
mv "$build" "$hidden"
[ "$("$prefix/bin/mcslam" --version)" = "mcslam $(sed -n 's/^#define MCSLAM_VERSION_STRING "\(.*\)"/\1/p' "$prefix/include/mcslam/version.hpp")" ] \
  || fail "mcslam --version does not match mcslam/version.hpp"

echo "test_package: building examples/embed against the prefix"
cp -r "$src/examples/embed" "$work/embed-src"
cmake -S "$work/embed-src" -B "$work/embed-build" -G Ninja -DCMAKE_PREFIX_PATH="$prefix" \
      -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF > "$work/embed-configure.log" \
  || { cat "$work/embed-configure.log"; fail "configuring examples/embed"; }
grep -q "mcslam .* from $prefix/lib/cmake/mcslam" "$work/embed-configure.log" \
  || { cat "$work/embed-configure.log"; fail "find_package(mcslam) did not find the prefix"; }
cmake --build "$work/embed-build" -j "$jobs" > "$work/embed-build.log" \
  || { cat "$work/embed-build.log"; fail "building examples/embed"; }

echo "test_package: running the example and the installed CLI on a 30-frame synthetic sequence"
"$work/embed-build/embed" "$synth" > "$work/embed.txt" 2> "$work/embed.err" \
  || { cat "$work/embed.err"; fail "examples/embed failed"; }
cat "$work/embed.err"
grep -q "vocabulary $prefix/share/mcslam/orb_vocabulary.bin" "$work/embed.err" \
  || fail "the example did not take the vocabulary from the prefix"
"$prefix/bin/mcslam" run "$synth" --output "$work/run" --sequential -q > /dev/null \
  || fail "the installed mcslam run failed"
python3 - "$work/embed.txt" "$work/run/trajectory.txt" <<'PY' || fail "the example's poses differ from mcslam run's"
import sys
def load(path):
    return [[float(v) for v in line.split()] for line in open(path)
            if line.strip() and not line.startswith("#")]
a, b = load(sys.argv[1]), load(sys.argv[2])
assert len(a) == len(b) and len(a) >= 20, (len(a), len(b))
worst = max(abs(x - y) for ra, rb in zip(a, b) for x, y in zip(ra[:4], rb[:4]))
assert worst <= 1e-6, worst
print(f"test_package: {len(a)} poses, the example's and mcslam run's agree to {worst:.1e} m")
PY

# The installed Python package (when the build has it), also with the build tree away.
pydir=$(find "$prefix/lib" -maxdepth 3 -type d -path '*/dist-packages/mcslam' | head -1)
if [ -n "$pydir" ]; then
  python=/usr/bin/python3; [ -x "$python" ] || python=python3
  voc=$(PYTHONPATH="$(dirname "$pydir")" "$python" -c \
        'import mcslam; print(mcslam.__version__, mcslam.Settings().vocabulary)') \
    || fail "import mcslam from $pydir"
  [ "$voc" = "$("$prefix/bin/mcslam" --version | cut -d' ' -f2) $prefix/share/mcslam/orb_vocabulary.bin" ] \
    || fail "the installed Python package says '$voc'"
  echo "test_package: python: $voc"
fi

echo "test_package: pkg-config"
export PKG_CONFIG_PATH="$prefix/lib/pkgconfig"
flags=$(pkg-config --cflags --libs mcslam) || fail "pkg-config --cflags --libs mcslam"
echo "  $flags"
cat > "$work/pc.cpp" <<'CPP'
#include <mcslam/mcslam.hpp>
#include <iostream>
int main() {
  std::cout << mcslam::version() << " " << mcslam::find_data_file("orb_vocabulary.bin") << "\n";
  return mcslam::version() == MCSLAM_VERSION_STRING ? 0 : 1;
}
CPP
# shellcheck disable=SC2086
c++ -std=c++20 -O1 "$work/pc.cpp" -o "$work/pc" $flags > "$work/pc.log" 2>&1 \
  || { cat "$work/pc.log"; fail "compiling with pkg-config's flags"; }
out=$(MCSLAM_DATA_DIR="$(pkg-config --variable=datadir mcslam)" "$work/pc") \
  || fail "the pkg-config program failed"
case "$out" in *"$prefix/lib/pkgconfig/../../share/mcslam/orb_vocabulary.bin"|*"$prefix/share/mcslam/orb_vocabulary.bin") ;;
  *) fail "the pkg-config program found its vocabulary at '$out'" ;; esac
echo "test_package: passed"
