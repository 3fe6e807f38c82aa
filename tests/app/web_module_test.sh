#!/usr/bin/env bash
# Runs a test of the web pages' shared modules (an .mjs file) in node, bundled with the esbuild
# and npm packages of web/report (scripts/install-deps.sh installs them).
# Usage: web_module_test.sh TEST.mjs OUT_DIR
# Exit 77 (skipped) without node or esbuild, unless MCSLAM_STRICT_TESTS=1 (CI).
set -uo pipefail
test_file="$1"
out="$2"
here="$(cd "$(dirname "$0")" && pwd)"
web="$here/../../web/report"
# shellcheck source=skip.sh
source "$(dirname "$0")/skip.sh"
command -v node > /dev/null 2>&1 || skip "no node"
[ -x "$web/node_modules/.bin/esbuild" ] || skip "no esbuild in web/report (run scripts/install-deps.sh)"
mkdir -p "$out"
bundle="$out/$(basename "$test_file" .mjs).bundle.mjs"
NODE_PATH="$web/node_modules" "$web/node_modules/.bin/esbuild" "$test_file" --bundle --platform=node \
  --format=esm --outfile="$bundle" --log-level=warning || exit 1
node "$bundle"
