#!/usr/bin/env bash
# report.html in a real browser: a small `mcslam bench` (a dynamic synthetic room, the same room
# without ground truth, and a sequence whose runs fail) writes it, then headless Chromium opens it
# (web/report/check-report.mjs): no console errors, nothing fetched, tables, plots and the 3D view
# present and drawn, and a screenshot (OUT/report.png).
# Usage: bench_report_browser.sh MCSLAM_EXE OUT_DIR
# Exit 77 (skipped) without Node.js, Chromium or the report's scripts, unless MCSLAM_STRICT_TESTS=1
# (CI), where a skip is a failure.
set -uo pipefail
exe="$1"
out="$2"
here="$(cd "$(dirname "$0")" && pwd)"
check="$here/../../web/report/check-report.mjs"
# shellcheck source=skip.sh
source "$(dirname "$0")/skip.sh"
command -v node > /dev/null 2>&1 || skip "no node"
[ -f "$(dirname "$exe")/report/report.js" ] || skip "report scripts not built (run scripts/install-deps.sh)"

rm -rf "$out"
mkdir -p "$out/data"
"$exe" synth --output "$out/data/room_dynamic" --frames 60 --depth-noise --dynamic --start-time 0.3 -q || exit 1
cp -r "$out/data/room_dynamic" "$out/data/room_no_groundtruth"
rm "$out/data/room_no_groundtruth/groundtruth.txt"
cp -r "$out/data/room_dynamic" "$out/data/room_broken"
for f in "$out"/data/room_broken/depth/*.png; do printf 'not a png' > "$f"; done

"$exe" bench "$out/data" --output "$out/bench" --runs 1 --configs points,planes,full -q
rc=$?
if [ $rc -ne 2 ]; then echo "expected exit 2 (the broken room's runs fail), got $rc"; exit 1; fi
[ -f "$out/bench/report.html" ] || { echo "no report.html"; exit 1; }

node "$check" "$out/bench/report.html" "$out/report.png"
rc=$?
[ $rc -eq 77 ] && skip "the browser check could not run"
exit $rc
