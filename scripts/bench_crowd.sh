#!/usr/bin/env bash
# Real-crowd benchmark: Bonn crowd (../shared/data/bonn/rgbd_bonn_crowd*) with the YOLOv8n
# detector, in the default threaded mode, each variant N times (median, min-max), scored with
# the Bonn marker-to-camera transform. Runs are interleaved (run 1 of every variant, then run 2,
# ...) so that a machine's drift hits every variant alike. The variants take one part of the
# object handling away:
#   default        - everything (class prior, boxes carried forward, background kept, movers,
#                    cold start, one OpenCV thread)
#   wait           - --wait-detections: every frame waits for its own boxes (fresh, slower)
#   no-propagation - boxes of earlier frames only grown, not carried by their features
#   no-background  - every feature inside a moving object's box left out
#   no-movers      - no search for motion without a box
#   no-prior       - people judged by Algorithm 1 alone, as other objects (before the prior)
#   no-detector    - geometry only
#   no-cold-start  - frames never wait for their boxes (system.cold_start_keyframes: 0)
#   moving-density - ORB keeps movers' regions no denser than the image (orb.moving_density: 1)
#   opencv-pool    - OpenCV's thread pool on every core (system.opencv_threads: 0)
#   before-23      - no-cold-start and opencv-pool together, LSD lines in real time too: the
#                    behaviour before issue 23
#   cold, cold-before-23, cold-moving-density - default / before-23 / moving-density from
#                    frame 240 (people in view from the first frame)
#   realtime, realtime-before-23, realtime-lsd - default / before-23 / LSD lines
#                    (lines.detector: lsd) with --realtime
#   lsd, cold-lsd, realtime-fld - OpenCV's LSD instead of the region detector (the default
#                    offline before), and FLD in real time (the default there before)
#   no-established, cold-no-established - every observation in the pose at once, as ORB-SLAM2
#                    (tracker.established_age: 0), instead of the established landmarks first
#   model-size, cold-model-size, realtime-model-size - default / cold / realtime with the
#                    detector at the model's own input size (system.detector_scale: 0; 320x320
#                    for yolov8n_320) instead of the image scaled by 0.35 (224x192)
# It prints ATE (whole run, and frames before / after the people enter at frame 240), tracked
# share, frames/s, tracking median, the detector's pass time and the age of the boxes used,
# the IoU of carried boxes against the detector's next boxes (and of boxes only grown), the
# frames where a moving region without a box was found, and for real-time runs the share of
# frames processed and the latency p95.
# Usage: scripts/bench_crowd.sh [--runs N] [--output DIR] [--model M.onnx] [--variants a,b,...]
#                               [--max-frames N] [SEQ_DIR]
#   --max-frames N  only the first N frames of each run (0: all; a quick check)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/common.sh
runs=3
out=results/bench_crowd
model=../shared/models/yolov8n_320.onnx
variants=default,wait,no-propagation,no-background,no-movers,no-prior,no-detector
seq=""
max_frames=0
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --output) out="$2"; shift 2 ;;
    --model) model="$2"; shift 2 ;;
    --variants) variants="$2"; shift 2 ;;
    --max-frames) max_frames="$2"; shift 2 ;;
    -*) echo "bench_crowd: unknown option $1" >&2; exit 2 ;;
    *) seq="$1"; shift ;;
  esac
done
require_mcslam bench_crowd
[ -n "$seq" ] || seq=$(ls -d ../shared/data/bonn/rgbd_bonn_crowd* 2>/dev/null | head -1 || true)
[ -n "$seq" ] && [ -f "$seq/rgb.txt" ] || { echo "bench_crowd: no Bonn crowd sequence (give SEQ_DIR)" >&2; exit 1; }
[ -f "$model" ] || { echo "bench_crowd: $model: model not found (--model)" >&2; exit 1; }
mkdir -p "$out/runs"

settings() {  # variant -> settings file (empty: none)
  local file="$out/$1.yaml"
  case "$1" in
    no-propagation) printf 'dynamics:\n  propagate_boxes: false\n' > "$file" ;;
    no-background) printf 'dynamics:\n  separate_background: false\n' > "$file" ;;
    no-movers) printf 'dynamics:\n  find_movers: false\n' > "$file" ;;
    no-prior) printf 'dynamics:\n  person_prior: false\n' > "$file" ;;
    no-cold-start) printf 'system:\n  cold_start_keyframes: 0\n' > "$file" ;;
    moving-density|cold-moving-density) printf 'orb:\n  moving_density: 1\n' > "$file" ;;
    realtime-lsd|lsd|cold-lsd) printf 'lines:\n  detector: lsd\n' > "$file" ;;
    realtime-fld) printf 'lines:\n  detector: fld\n' > "$file" ;;
    opencv-pool) printf 'system:\n  opencv_threads: 0\n' > "$file" ;;
    no-established|cold-no-established) printf 'tracker:\n  established_age: 0\n' > "$file" ;;
    model-size|cold-model-size|realtime-model-size)
      printf 'system:\n  detector_scale: 0\n' > "$file" ;;
    before-23|cold-before-23|realtime-before-23)
      printf 'system:\n  cold_start_keyframes: 0\n  opencv_threads: 0\nlines:\n  detector: lsd\n' \
        > "$file" ;;
    *) return 0 ;;
  esac
  echo "$file"
}

IFS=, read -r -a names <<< "$variants"
for v in "${names[@]}"; do  # check every name before the first run
  case "$v" in
    default|wait|no-propagation|no-background|no-movers|no-prior|no-detector|no-cold-start) ;;
    moving-density|opencv-pool|before-23|cold|cold-before-23|cold-moving-density) ;;
    realtime|realtime-before-23|realtime-lsd|realtime-fld|lsd|cold-lsd) ;;
    model-size|cold-model-size|realtime-model-size|no-established|cold-no-established) ;;
    *) echo "bench_crowd: unknown variant $v" >&2; exit 2 ;;
  esac
done
# The first frame of the segment with people (frame 240 of the sequence).
t=$(grep -v '^#' "$seq/rgb.txt" | sed -n 241p | cut -d' ' -f1)
for i in $(seq 1 "$runs"); do
  for v in "${names[@]}"; do
    args=(--model "$model")
    case "$v" in
      wait) args+=(--wait-detections) ;;
      no-detector) args=() ;;
      cold|cold-before-23|cold-moving-density|cold-model-size|cold-no-established|cold-lsd)
        args+=(--first-frame 240) ;;
      realtime|realtime-before-23|realtime-lsd|realtime-fld|realtime-model-size)
        args+=(--realtime) ;;
    esac
    file=$(settings "$v")
    [ -n "$file" ] && args+=(--config "$file")
    [ "$max_frames" -gt 0 ] && args+=(--max-frames "$max_frames")
    dir="$out/runs/$v-$i"
    echo "bench_crowd: $v run $i" >&2
    ./build/mcslam run "$seq" --output "$dir" "${args[@]}" -q 2> "$dir.err" ||
      echo "bench_crowd: $v run $i failed, see $dir.err" >&2
    # Segments before and after the people enter, each aligned on its own.
    if [ -f "$dir/trajectory.txt" ] && [ -f "$seq/groundtruth.txt" ]; then
      awk -v t="$t" '$1 < t' "$dir/trajectory.txt" > "$dir/before.txt"
      awk -v t="$t" '$1 >= t' "$dir/trajectory.txt" > "$dir/after.txt"
      for part in before after; do
        ./build/mcslam eval --gt "$seq/groundtruth.txt" --est "$dir/$part.txt" --bonn --json \
          > "$dir/$part.json" 2> /dev/null || rm -f "$dir/$part.json"
      done
    fi
  done
done

python3 - "$out" "$runs" "$variants" <<'PY'
import os, statistics, sys
sys.path.insert(0, "scripts")
from results_tables import load  # a JSON file, or None when it is missing or torn
out, runs, variants = sys.argv[1], int(sys.argv[2]), sys.argv[3].split(",")
def fmt(values, digits=4):
    values = [v for v in values if v is not None]
    if not values:
        return "-"
    m = statistics.median(values)
    if len(values) == 1:
        return f"{m:.{digits}f}"
    return f"{m:.{digits}f} ({min(values):.{digits}f}-{max(values):.{digits}f})"
print("| variant | ATE RMSE (m) | before people | with people | tracked | fps | tracking ms | detector pass ms | box age | carried IoU | grown IoU | mover frames | processed (real time) | latency p95 ms |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for v in variants:
    s = [load(os.path.join(out, "runs", f"{v}-{i}", "summary.json")) for i in range(1, runs + 1)]
    s = [x for x in s if x]
    if not s:
        print(f"| {v} | failed | | | | | | | | | | | | |")
        continue
    ate = [x.get("ate_rmse_m") for x in s]
    parts = {p: [(load(os.path.join(out, "runs", f"{v}-{i}", f"{p}.json")) or {}).get("ate_rmse_m")
                 for i in range(1, runs + 1)] for p in ("before", "after")}
    tracked = [x["tracked_ratio"] * 100 for x in s]
    fps = [x.get("frames_per_second") for x in s]
    ms = [x["stages"]["tracking_total"]["median_ms"] for x in s if "tracking_total" in x.get("stages", {})]
    dyn = [x.get("dynamics", {}) for x in s]
    iou = [d.get("propagation", {}).get("iou_median") for d in dyn if d.get("propagation", {}).get("measured")]
    stale = [d.get("propagation", {}).get("stale_iou_median") for d in dyn if d.get("propagation", {}).get("measured")]
    movers = [d.get("mover_frames") for d in dyn if "mover_frames" in d]
    passes = [d.get("detector_pass_ms", {}).get("median") for d in dyn if d.get("detector_passes")]
    age = [d.get("median_age_frames") for d in dyn if d.get("detector_passes")]
    rt = [x["realtime"] for x in s if x.get("realtime", {}).get("enabled")]
    processed = [r["processed_ratio"] * 100 for r in rt]
    latency = [r["latency_p95_ms"] for r in rt]
    print(f"| {v} | {fmt(ate)} | {fmt(parts['before'])} | {fmt(parts['after'])} | {fmt(tracked, 1)} % "
          f"| {fmt(fps, 1)} | {fmt(ms, 1)} | {fmt(passes, 0)} | {fmt(age, 0)} | {fmt(iou, 2)} "
          f"| {fmt(stale, 2)} | {fmt(movers, 0)} | {fmt(processed, 1)} | {fmt(latency, 0)} |")
PY
