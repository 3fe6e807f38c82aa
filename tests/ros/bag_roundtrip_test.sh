#!/usr/bin/env bash
# folder -> export-bag -> run FILE.bag gives the folder's trajectory (sequential mode), and the
# bag carries the camera, the ground truth and both depth encodings.
set -euo pipefail
MCSLAM=$1; TOOL=$2; WORK=$3
rm -rf "$WORK"; mkdir -p "$WORK"
fail() { echo "FAIL: $*"; exit 1; }

"$MCSLAM" synth -o "$WORK/seq" --frames 40 --width 320 --height 240 -q
"$MCSLAM" export-bag "$WORK/seq" "$WORK/seq.bag" -q
[ -f "$WORK/seq.bag" ] || fail "no bag written"
ls "$WORK" | grep -q tmp- && fail "a temporary file was left behind"

"$MCSLAM" run "$WORK/seq" -o "$WORK/folder" --sequential -q
"$MCSLAM" run "$WORK/seq.bag" -o "$WORK/bag" --sequential -q
cmp "$WORK/folder/trajectory.txt" "$WORK/bag/trajectory.txt" ||
  fail "the bag's trajectory differs from the folder's"
grep -q '"ate_rmse_m"' "$WORK/bag/summary.json" || fail "no ground truth read from the bag"
grep -q "camera_settings" "$WORK/bag/summary.json" || fail "camera not taken from the bag"
python3 - "$WORK" <<'PY'
import json, sys
a = json.load(open(sys.argv[1] + "/folder/summary.json"))
b = json.load(open(sys.argv[1] + "/bag/summary.json"))
print("ATE folder %.6f m, bag %.6f m" % (a["ate_rmse_m"], b["ate_rmse_m"]))
assert a["ate_rmse_m"] == b["ate_rmse_m"], "ATE differs"
PY

# Millimetre depth and rgb8 colour (RealSense-style encodings) also read back.
"$MCSLAM" export-bag "$WORK/seq" "$WORK/seq_mm.bag" --rgb-encoding rgb8 --depth-encoding 16UC1 -q
"$MCSLAM" run "$WORK/seq_mm.bag" -o "$WORK/mm" --sequential -q --max-frames 10
[ "$(grep -vc '^#' "$WORK/mm/trajectory.txt")" -ge 9 ] || fail "16UC1/rgb8 bag not tracked"

# RealSense topic names: written and read with the preset.
"$MCSLAM" export-bag "$WORK/seq" "$WORK/seq_rs.bag" --topics realsense -q
"$MCSLAM" run "$WORK/seq_rs.bag" -o "$WORK/rs" --topics realsense --sequential -q --max-frames 10
echo "PASS"
