#!/usr/bin/env bash
# Installs, builds and runs the whole test suite (GoogleTest through ctest).
# Usage: scripts/test.sh [preset]   (release by default; asan for AddressSanitizer + UBSan)
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
bash scripts/build.sh "$preset"
ctest --preset "$preset" -j "$(nproc)"
