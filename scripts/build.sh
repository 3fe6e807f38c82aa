#!/usr/bin/env bash
# Installs dependencies (Debian 12 packages) and builds mcslam into ./build (CLI: ./build/mcslam).
# Usage: scripts/build.sh [preset]   (release by default; also debug, asan, tsan, fuzz)
# The install script runs only when it, or the bench report's package-lock.json, changed since it
# last succeeded on this machine (a stamp in .deps-installed.stamp), or when MCSLAM_INSTALL_DEPS=1.
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
stamp=.deps-installed.stamp
want=$(cat scripts/install-deps.sh web/report/package-lock.json | sha256sum | cut -d' ' -f1)
if [ "${MCSLAM_INSTALL_DEPS:-0}" = 1 ] || [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ] \
   || [ ! -d web/report/node_modules ]; then
  bash scripts/install-deps.sh
  echo "$want" > "$stamp"
else
  echo "build: dependencies installed (scripts/install-deps.sh unchanged since; MCSLAM_INSTALL_DEPS=1 reruns it)"
fi
cmake --preset "$preset" > /dev/null
cmake --build --preset "$preset" -j "$(nproc)"
