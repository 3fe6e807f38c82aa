#!/usr/bin/env bash
# The current figures in one command: builds mcslam, measures every capability on this machine
# and writes docs/results.md (a generated file) and the results table of README.md (between
# its `results:begin` and `results:end` markers), and prints that table.
#
#   reference speed   freiburg1_rpy with yolov8n_320, threaded (the figure to compare machines by)
#   tracking          freiburg1_rpy and Bonn crowd part1 (threaded, sequential, --first-frame 240,
#                     --realtime): ATE of trajectory.txt and of trajectory_online.txt, RPE over one
#                     frame, tracked share, speed; freiburg1_rpy's feature kinds' cost
#   objects           Bonn crowd part1 with parts of the object pipeline switched off
#                     (scripts/bench_crowd.sh)
#   synthetic         the dynamic rooms (scripts/bench_dynamic.sh) and the synthetic crowd
#                     (sequential, deterministic, ground-truth boxes)
#   navigation map    ghost rate and completeness, Bonn REF/FULL (scripts/bench_mapping.sh)
#
# Threaded runs differ from run to run: each is run N times (median, min-max); sequential runs
# are deterministic and run once. About 20 minutes on a 2-core machine with N = 3.
# Needs ../shared/data (tum/rgbd_dataset_freiburg1_rpy, bonn/rgbd_bonn_crowd_part1) and
# ../shared/models/yolov8n_320.onnx.
# Usage: scripts/results.sh [--runs N] [--output DIR] [--no-build] [--max-frames N]
#   --max-frames N  cut every real sequence (a quick check of the script; writes DIR/results.md
#                   only, not docs/ nor README.md)
set -euo pipefail
cd "$(dirname "$0")/.."
runs=3
out=results/current
build=1
max_frames=0
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --output) out="$2"; shift 2 ;;
    --no-build) build=0; shift ;;
    --max-frames) max_frames="$2"; shift 2 ;;
    *) echo "results: unknown option $1" >&2; exit 2 ;;
  esac
done
rpy=../shared/data/tum/rgbd_dataset_freiburg1_rpy
bonn=../shared/data/bonn/rgbd_bonn_crowd_part1
model=../shared/models/yolov8n_320.onnx
for f in "$rpy/rgb.txt" "$bonn/rgb.txt" "$model"; do
  [ -f "$f" ] || { echo "results: $f not found" >&2; exit 1; }
done
start=$(date +%s)
[ "$build" = 1 ] && bash scripts/build.sh release
exe=./build/mcslam
[ -x "$exe" ] || { echo "results: $exe not found" >&2; exit 1; }
rm -rf "$out"
mkdir -p "$out/runs" "$out/synthetic"
cut=()
[ "$max_frames" -gt 0 ] && cut=(--max-frames "$max_frames")
declare -A seconds
lap=$(date +%s)
part_done() {  # name: records the seconds since the last part
  local now
  now=$(date +%s)
  seconds[$1]=$((now - lap))
  lap=$now
  echo "results: $1 done in ${seconds[$1]} s" >&2
}
run() {  # dir, then `mcslam run` arguments
  local dir="$1"; shift
  echo "results: $(basename "$dir")" >&2
  "$exe" run "$@" "${cut[@]}" --output "$dir" -q 2> "$dir.err" ||
    echo "results: $dir failed, see $dir.err" >&2
}

# Tracking on freiburg1_rpy: threaded runs interleaved (run 1 of each, then run 2, ...).
for i in $(seq 1 "$runs"); do
  run "$out/runs/rpy-detector-$i" "$rpy" --model "$model"
  run "$out/runs/rpy-geometry-$i" "$rpy"
  run "$out/runs/rpy-points-$i" "$rpy" --features points
done
run "$out/runs/rpy-sequential-1" "$rpy" --model "$model" --sequential
part_done freiburg1_rpy

# Bonn crowd part1: the object pipeline's variants, then one sequential run.
variants=default,cold,realtime,no-prior,no-detector,no-propagation,no-background,no-movers
[ "$max_frames" -gt 0 ] && variants=default,cold,realtime
mkdir -p "$out/crowd"
bash scripts/bench_crowd.sh --runs "$runs" --output "$out/crowd" --model "$model" \
  --variants "$variants" --max-frames "$max_frames" "$bonn" > "$out/crowd/table.md"
run "$out/runs/bonn-sequential-1" "$bonn" --model "$model" --sequential
part_done bonn

# Synthetic: the dynamic rooms, and the crowd (sequential, ground-truth boxes).
frames=300
[ "$max_frames" -gt 0 ] && frames="$max_frames"
bash scripts/bench_dynamic.sh --output "$out/dynamic" --frames "$frames" --no-real > /dev/null
printf 'tracker:\n  established_age: 0\n' > "$out/no_established.yaml"
render() {  # name, then synth options
  local dir="$out/synthetic/$1"; shift
  "$exe" synth --output "$dir" --frames "$frames" --seed 1 --depth-noise -q "$@"
}
render room --dynamic --no-person
render undetected --dynamic --people 3 --undetected-people 1
render crowd4 --dynamic --people 4 --undetected-people 1
for s in room undetected crowd4; do
  run "$out/runs/synth-$s" "$out/synthetic/$s" --sequential \
    --detections "$out/synthetic/$s/detections.json"
done
run "$out/runs/synth-undetected-no-established" "$out/synthetic/undetected" --sequential \
  --detections "$out/synthetic/undetected/detections.json" -c "$out/no_established.yaml"
part_done synthetic

# The navigation map.
map_args=(--runs "$runs" --frames "$frames")
[ "$max_frames" -gt 0 ] && map_args+=(--no-bonn)
mkdir -p "$out/mapping"
bash scripts/bench_mapping.sh --output "$out/mapping" "${map_args[@]}" > "$out/mapping/table.md"
part_done mapping

# Trajectories scored with `mcslam eval`: trajectory.txt, trajectory_online.txt and
# trajectory_unsmoothed.txt (the final trajectory before its positions are smoothed).
score() {  # run dir, ground truth, then eval options
  local dir="$1" gt="$2"; shift 2
  for t in trajectory trajectory_online trajectory_unsmoothed; do
    [ -f "$dir/$t.txt" ] && "$exe" eval --gt "$gt" --est "$dir/$t.txt" --json "$@" \
      > "$dir/$t.eval.json" 2> /dev/null || rm -f "$dir/$t.eval.json"
  done
}
for d in "$out"/runs/rpy-*/; do score "$d" "$rpy/groundtruth.txt"; done
for d in "$out"/runs/bonn-*/ "$out"/crowd/runs/*/; do
  [ -d "$d" ] && score "$d" "$bonn/groundtruth.txt" --bonn
done
for s in room undetected crowd4; do
  for d in "$out/runs/synth-$s"*/; do score "$d" "$out/synthetic/$s/groundtruth.txt"; done
done
total=$(( $(date +%s) - start ))

# docs/results.md and README.md's table (printed too); a cut run writes DIR/results.md only.
docs=docs/results.md readme=README.md
[ "$max_frames" -gt 0 ] && docs="$out/results.md" readme=""
python3 scripts/results_tables.py --output "$out" --runs "$runs" --seconds "$total" \
  --docs "$docs" --readme "$readme" --max-frames "$max_frames" \
  --machine "$(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')"
