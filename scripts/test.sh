#!/usr/bin/env bash
# Installs, builds and runs the whole test suite (GoogleTest through ctest).
# Usage: scripts/test.sh [preset]   (release by default; asan: AddressSanitizer + UBSan, tsan:
# ThreadSanitizer, fuzz: clang + ASan + UBSan unit tests of the lower modules, as in CI)
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
bash scripts/build.sh "$preset"
ctest --preset "$preset" -j "$(nproc)"
