#!/usr/bin/env bash
# Dynamic-scene benchmark (Algorithms 1 and 2): renders synthetic rooms with a person moving
# freely and a chair sliding on the floor (several seeds, speeds and sizes), runs mcslam on each
#   geometry - no boxes at all;
#   alg1     - ground-truth boxes (--detections), dynamic objects excluded, no constraints;
#   full     - ground-truth boxes, dynamic objects excluded, moving constraints (9), (10);
# and prints ATE per configuration and, per object, how often it was classified dynamic /
# constrained on the frames where it moves (and static objects on any frame). With the real
# data and model present it also runs freiburg1_rpy without and with the yolov8n_320 detector
# (threaded: overlapped detection; and --wait-detections) for accuracy and speed, N times each.
# Synthetic runs are sequential (deterministic), once per configuration.
# Usage: scripts/bench_dynamic.sh [--runs N] [--output DIR] [--frames N] [--no-real]
#   --no-real  the synthetic scenes only
set -euo pipefail
cd "$(dirname "$0")/.."
runs=1
out=results/bench_dynamic
frames=300
real_runs=1
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --output) out="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --no-real) real_runs=0; shift ;;
    *) echo "bench_dynamic: unknown option $1" >&2; exit 2 ;;
  esac
done
exe=./build/mcslam
[ -x "$exe" ] || { echo "bench_dynamic: $exe not found; run scripts/build.sh first" >&2; exit 1; }
mkdir -p "$out"

# name seed person_speed person_scale chair_speed chair_scale
scenes=(
  "dyn_s1_default 1 1.0 1.0 0.5 1.0"
  "dyn_s2_large_fast 2 1.5 1.6 0.3 1.4"
  "dyn_s3_small_slow 3 0.5 0.6 0.8 0.6"
  "dyn_s4_default 4 1.0 1.0 0.5 1.0"
)
seqs=()
for spec in "${scenes[@]}"; do
  read -r name seed ps pscale cs cscale <<< "$spec"
  dir="$out/synthetic/$name"
  if [ ! -f "$dir/objects.json" ]; then
    echo "bench_dynamic: rendering $name" >&2
    "$exe" synth --output "$dir" --frames "$frames" --seed "$seed" --depth-noise --dynamic \
      --person-speed "$ps" --person-scale "$pscale" --chair-speed "$cs" --chair-scale "$cscale" -q
  fi
  seqs+=("$dir")
done

run() {  # dir args...
  local dir="$1"; shift
  if ! "$exe" run "$@" --output "$dir" -q 2> "$dir.err"; then
    echo "bench_dynamic: run failed, see $dir.err" >&2
  fi
}
# Sequential runs are deterministic: one per configuration.
for seq in "${seqs[@]}"; do
  name=$(basename "$seq")
  mkdir -p "$out/runs/$name"
  echo "bench_dynamic: $name" >&2
  run "$out/runs/$name/geometry-1" "$seq" --sequential
  run "$out/runs/$name/alg1-1" "$seq" --sequential --detections "$seq/detections.json" \
    --no-constraints
  run "$out/runs/$name/full-1" "$seq" --sequential --detections "$seq/detections.json"
done

real=../shared/data/tum/rgbd_dataset_freiburg1_rpy
model=../shared/models/yolov8n_320.onnx
if [ "$real_runs" = 1 ] && [ -f "$real/rgb.txt" ] && [ -f "$model" ]; then
  mkdir -p "$out/runs/fr1_rpy"
  for i in $(seq 1 "$runs"); do
    echo "bench_dynamic: freiburg1_rpy run $i/$runs" >&2
    run "$out/runs/fr1_rpy/geometry-$i" "$real"
    run "$out/runs/fr1_rpy/detector-$i" "$real" --model "$model"
    run "$out/runs/fr1_rpy/detector_wait-$i" "$real" --model "$model" --wait-detections
  done
fi

python3 - "$out" "$runs" "${seqs[@]}" <<'PY'
import json, os, statistics, sys
out, real_runs, seqs = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
runs = 1  # synthetic runs are sequential (deterministic)
def med(xs): return statistics.median(xs) if xs else float('nan')
def load(p):
    return json.load(open(p)) if os.path.exists(p) else None
def iou(a, b):
    x0, y0 = max(a[0], b[0]), max(a[1], b[1])
    x1, y1 = min(a[0] + a[2], b[0] + b[2]), min(a[1] + a[3], b[1] + b[3])
    inter = max(0, x1 - x0) * max(0, y1 - y0)
    union = a[2] * a[3] + b[2] * b[3] - inter
    return inter / union if union > 0 else 0

lines = ["| sequence | config | ATE RMSE m (median) | tracked % | dynamics ms median | person dynamic % | chair constrained % | chair dynamic-or-constrained % | static objects flagged % |",
         "|---|---|---|---|---|---|---|---|---|"]
for seq in seqs:
    name = os.path.basename(os.path.normpath(seq))
    gt = load(os.path.join(seq, "objects.json"))
    kinds = {o["index"]: (o["class"], o["motion"]) for o in gt["objects"]}
    gt_frames = {round(f["timestamp"], 6): f for f in gt["frames"]}
    for config in ("geometry", "alg1", "full"):
        ates, cov, dyn_ms = [], [], []
        counts = {"free": [0, 0], "slide": [0, 0, 0], "static": [0, 0]}
        for i in range(1, runs + 1):
            d = os.path.join(out, "runs", name, f"{config}-{i}")
            s = load(os.path.join(d, "summary.json"))
            if not s:
                continue
            if "ate_rmse_m" in s: ates.append(s["ate_rmse_m"])
            cov.append(s["tracked_ratio"])
            if "dynamics" in s["stages"]: dyn_ms.append(s["stages"]["dynamics"]["median_ms"])
            ob = load(os.path.join(d, "objects.json"))
            if not ob:
                continue
            for f in ob["frames"]:
                g = gt_frames.get(round(f["timestamp"], 6))
                if not g: continue
                for go in g["objects"]:
                    cls, motion = kinds[go["index"]]
                    if go["visible_pixels"] == 0 or go["box"][2] == 0: continue
                    best, state = 0.0, None
                    for o in f["objects"]:
                        if o["class"] != cls: continue
                        v = iou(o["box"], go["box"])
                        if v > best: best, state = v, o["state"]
                    if state is None or best < 0.5: continue
                    if motion == "static":
                        counts["static"][0] += 1
                        counts["static"][1] += state != "static"
                    elif go["moving"]:
                        c = counts[motion]
                        c[0] += 1
                        if motion == "free":
                            c[1] += state == "dynamic"
                        else:
                            c[1] += state == "constrained"
                            c[2] += state != "static"
        pct = lambda a, b: f"{100.0 * a / b:.1f} ({b})" if b else "-"
        ate = f"{med(ates):.4f}" if ates else "n/a"
        lines.append(f"| {name} | {config} | {ate} | {100 * med(cov):.1f} | "
                     + (f"{med(dyn_ms):.2f}" if dyn_ms else "-") + " | "
                     + pct(counts["free"][1], counts["free"][0]) + " | "
                     + pct(counts["slide"][1], counts["slide"][0]) + " | "
                     + pct(counts["slide"][2], counts["slide"][0]) + " | "
                     + pct(counts["static"][1], counts["static"][0]) + " |")
text = "\n".join(lines) + "\n"
real = os.path.join(out, "runs", "fr1_rpy")
if os.path.isdir(real):
    rows = ["| freiburg1_rpy | ATE RMSE m median (min-max) | tracked % | fps median | tracking ms median | detector ms median | fresh boxes % | dynamics ms median |",
            "|---|---|---|---|---|---|---|---|"]
    for config in ("geometry", "detector", "detector_wait"):
        s = [x for x in (load(os.path.join(real, f"{config}-{i}", "summary.json")) for i in range(1, real_runs + 1)) if x]
        if not s:
            rows.append(f"| {config} | failed | | | | | | |"); continue
        ate = [x["ate_rmse_m"] for x in s if "ate_rmse_m" in x]
        det = [x["dynamics"]["detector_ms"]["median"] for x in s if x["dynamics"]["detector_ms"]["count"]]
        fresh = [x["dynamics"]["fresh_ratio"] for x in s if x["dynamics"]["frames_with_boxes"]]
        dms = [x["stages"]["dynamics"]["median_ms"] for x in s if "dynamics" in x["stages"]]
        rows.append(f"| {config} | {med(ate):.4f} ({min(ate):.4f}-{max(ate):.4f}) | {100 * med([x['tracked_ratio'] for x in s]):.1f} | "
                    f"{med([x['frames_per_second'] for x in s]):.1f} | {med([x['stages']['tracking_total']['median_ms'] for x in s]):.1f} | "
                    + (f"{med(det):.1f}" if det else "-") + " | " + (f"{100 * med(fresh):.0f}" if fresh else "-") + " | "
                    + (f"{med(dms):.2f}" if dms else "-") + " |")
    text += "\n" + "\n".join(rows) + "\n"
print(text)
open(os.path.join(out, "table.md"), "w").write(text)
PY
