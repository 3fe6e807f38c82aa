#!/usr/bin/env bash
# Installs, builds and runs the whole test suite (GoogleTest and pytest through ctest), then, for
# the release build, the installed package on its own (scripts/test_package.sh).
# Usage: scripts/test.sh [preset]   (release by default; asan: AddressSanitizer + UBSan, tsan:
# ThreadSanitizer, fuzz: clang + ASan + UBSan unit tests of the lower modules, as in CI)
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
bash scripts/build.sh "$preset"
ctest --preset "$preset" -j "$(nproc)"
if [ "$preset" = release ]; then bash scripts/test_package.sh build; fi
