#!/usr/bin/env bash
# Installs dependencies (Debian 12 packages) and builds mcslam into ./build (CLI: ./build/mcslam).
# Usage: scripts/build.sh [preset]   (release by default; also debug, asan, tsan, fuzz)
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
bash scripts/install-deps.sh
cmake --preset "$preset" > /dev/null
cmake --build --preset "$preset" -j "$(nproc)"
