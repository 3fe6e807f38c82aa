#!/usr/bin/env bash
# The benchmark in one command: installs and builds, renders three synthetic rooms (textured,
# low-texture, and dynamic: a person walking and a chair pushed on the floor) into DIR/data, then
# runs `mcslam bench` on them and on the real sequences of ../shared/data (when present), with the
# YOLOv8n detector of ../shared/models (when present) for the real ones. Prints the tables and
# writes DIR/results.md, results.json, runs.csv and report.html.
# Usage: scripts/bench.sh [--runs N] [--output DIR] [--no-synthetic | --synthetic-only]
#                         [any other `mcslam bench` option, e.g. --configs points,full]
set -euo pipefail
cd "$(dirname "$0")/.."
runs=3
out=results/bench
synthetic=1
real=1
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --output) out="$2"; shift 2 ;;
    --no-synthetic) synthetic=0; shift ;;
    --synthetic-only) real=0; shift ;;
    *) extra+=("$1"); shift ;;
  esac
done
bash scripts/build.sh release
exe=./build/mcslam
roots=()
if [ "$real" = 1 ] && [ -d ../shared/data ]; then roots+=(../shared/data); fi
if [ "$synthetic" = 1 ]; then
  data="$out/data"
  render() {  # folder, then synth options
    local dir="$data/$1"; shift
    [ -f "$dir/rgb.txt" ] || "$exe" synth --output "$dir" --frames 300 --depth-noise -q "$@"
  }
  render synthetic_room_rich --texture rich
  render synthetic_room_low --texture low
  render synthetic_room_dynamic --dynamic
  roots+=("$data")
fi
[ ${#roots[@]} -gt 0 ] || { echo "bench: no sequences (../shared/data is absent)" >&2; exit 1; }
model=../shared/models/yolov8n_320.onnx
model_args=()
[ -f "$model" ] && model_args=(--model "$model")
"$exe" bench "${roots[@]}" --runs "$runs" --output "$out" "${model_args[@]}" "${extra[@]}"
