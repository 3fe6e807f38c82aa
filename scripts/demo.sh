#!/usr/bin/env bash
# Installs, builds and runs mcslam on a default input: TUM freiburg1_rpy from ../shared/data
# when it is there, otherwise a synthetic sequence that mcslam renders itself.
# Usage: scripts/demo.sh [output_dir]
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-results/demo}"
bash scripts/build.sh release
seq="../shared/data/tum/rgbd_dataset_freiburg1_rpy"
if [ ! -f "$seq/rgb.txt" ]; then
  seq="results/synthetic_room"
  if [ ! -f "$seq/rgb.txt" ]; then
    echo "== ../shared/data is not here: rendering a synthetic sequence into $seq"
    ./build/mcslam synth --output "$seq" --frames 300 --depth-noise
  fi
fi
echo "== mcslam run $seq --output $out --save-map"
./build/mcslam run "$seq" --output "$out" --save-map
echo "== done: trajectory, keyframes, timings, summary (ATE, frame rate) and the map (map.ply, map.json) are in $out/"
