#!/usr/bin/env bash
# Installs, builds and runs mcslam on a default input: TUM freiburg1_rpy from ../shared/data
# when it is there, otherwise a synthetic dynamic scene that mcslam renders itself (a person
# walking, a chair pushed on the floor). Object boxes come from the YOLOv8n model in
# ../shared/models when it is there, otherwise (synthetic scene) from its ground-truth boxes.
# Usage: scripts/demo.sh [output_dir]
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-results/demo}"
bash scripts/build.sh release
seq="../shared/data/tum/rgbd_dataset_freiburg1_rpy"
if [ ! -f "$seq/rgb.txt" ]; then
  seq="results/synthetic_dynamic_room"
  if [ ! -f "$seq/rgb.txt" ]; then
    echo "== ../shared/data is not here: rendering a synthetic dynamic scene into $seq"
    ./build/mcslam synth --output "$seq" --frames 300 --depth-noise --dynamic
  fi
fi
boxes=()
model="../shared/models/yolov8n_320.onnx"
if [ -f "$model" ]; then
  boxes=(--model "$model")
elif [ -f "$seq/detections.json" ]; then
  boxes=(--detections "$seq/detections.json")
fi
echo "== mcslam run $seq --output $out --save-map --save-overlays ${boxes[*]}"
./build/mcslam run "$seq" --output "$out" --save-map --save-overlays "${boxes[@]}"
echo "== done: trajectory, keyframes, timings, summary (ATE, frame rate), objects.json, annotated"
echo "   frames (overlays/) and the map (map.ply, map.json) are in $out/"
