#!/usr/bin/env bash
# The live viewer in a real browser: `mcslam run --viewer` on a rendered dynamic room (played at
# its frame rate, --realtime, so that the run lasts while the page is checked), then headless
# Chromium opens the page (web/viewer/check-viewer.mjs): frames arrive, the map grows, "Fit view"
# frames it and the trajectory is drawn, the occupancy map's grid and voxels and the people's boxes are drawn and
# their switches hide and show them, pause and resume, localisation only and back, no console
# errors. The run (60 s of frames, longer than the check takes) is then stopped with SIGINT and
# must write its outputs, its summary.json recording the pause, the two switches and the
# occupancy snapshots sent.
# Usage: viewer_browser.sh MCSLAM_EXE OUT_DIR [SCREENSHOT_DIR]
# Exit 77 (skipped) without Node.js, Chromium or the viewer's scripts, unless
# MCSLAM_STRICT_TESTS=1 (CI), where a skip is a failure.
set -uo pipefail
exe="$1"
out="$2"
shots="${3:-$out}"
here="$(cd "$(dirname "$0")" && pwd)"
check="$here/../../web/viewer/check-viewer.mjs"
# shellcheck source=skip.sh
source "$(dirname "$0")/skip.sh"
command -v node > /dev/null 2>&1 || skip "no node"
[ -x "${CHROMIUM:-/usr/bin/chromium}" ] || skip "no chromium"
[ -f "$(dirname "$exe")/share/mcslam/viewer/viewer.js" ] || skip "viewer scripts not built (run scripts/install-deps.sh)"

rm -rf "$out"
mkdir -p "$out"
# 60 s of frames at 320x240: the check must end before the run does, and on a loaded 2-core
# machine it took longer than 30 s (a run of 30 s had ended before "localisation only, off
# again" could be checked). At this size 60 s of frames render in about half the time of 30 s
# of VGA frames.
"$exe" synth --output "$out/room" --frames 1800 --width 320 --height 240 --dynamic -q || exit 1

# Port 0: any free port; the run prints the address it listens on.
"$exe" run "$out/room" --output "$out/run" --detections "$out/room/detections.json" --realtime \
  --viewer 0 -q 2> "$out/run.err" &
run_pid=$!
url=""
for _ in $(seq 1 100); do
  url=$(grep -o 'http://127\.0\.0\.1:[0-9]*/' "$out/run.err" | head -n 1)
  [ -n "$url" ] && break
  kill -0 $run_pid 2> /dev/null || break
  sleep 0.2
done
if [ -z "$url" ]; then
  echo "the run printed no viewer address:"; cat "$out/run.err"; kill $run_pid 2> /dev/null; exit 1
fi
echo "viewer at $url"
node "$check" "$url" "$shots"
rc=$?
kill -INT $run_pid 2> /dev/null  # stop the run early: it writes its outputs (exit 130)
wait $run_pid
run_rc=$?
cat "$out/run.err"
[ $rc -eq 77 ] && skip "the browser check could not run"
[ $rc -ne 0 ] && exit $rc
[ $run_rc -ne 0 ] && [ $run_rc -ne 130 ] && { echo "the run failed: exit $run_rc"; exit 1; }
python3 - "$out/run/summary.json" << 'PY' || exit 1
import json, sys
s = json.load(open(sys.argv[1]))
c = s["controls"]
assert c["pauses"] >= 1 and c["paused_s"] > 1.0, c
assert [x["localize"] for x in c["localize_switches"]] == [True, False], c
assert s["viewer"]["connections"] >= 1 and s["viewer"]["frames_sent"] > 0, s["viewer"]
assert s["viewer"]["occupancy_sent"] >= 1, s["viewer"]
print("summary.json: controls", c, "viewer", s["viewer"])
PY
