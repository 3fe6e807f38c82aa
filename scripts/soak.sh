#!/usr/bin/env bash
# The soak run: a sequence played N times in a row as one stream (`mcslam run --repeat N`), the
# camera jumping back to the start at each pass. Prints per pass the frames tracked and lost,
# relocalisations, tracking time, fps, resident memory at the end of the pass, map size and the
# pass's ATE; then whether memory and tracking time stayed flat. Needs a build.
# Usage: scripts/soak.sh [--repeat N] [--output DIR] [--model ONNX|--no-model] [SEQUENCE_DIR]
# (default: 20 passes of ../shared/data/tum/rgbd_dataset_freiburg1_rpy, else of a synthetic room
# it renders; the detector ../shared/models/yolov8n_320.onnx when present)
set -euo pipefail
cd "$(dirname "$0")/.."
out=results/soak
repeat=20
seq=""
model=../shared/models/yolov8n_320.onnx
while [ $# -gt 0 ]; do
  case "$1" in
    --output) out="$2"; shift 2 ;;
    --repeat) repeat="$2"; shift 2 ;;
    --model) model="$2"; shift 2 ;;
    --no-model) model=""; shift ;;
    -*) echo "soak: unknown option $1" >&2; exit 1 ;;
    *) seq="$1"; shift ;;
  esac
done
source scripts/common.sh
require_mcslam soak
exe=./build/mcslam
mkdir -p "$out"
[ -n "$seq" ] || seq=$(default_sequence "$out")
model_args=()
if [ -n "$model" ] && [ -f "$model" ]; then model_args=(--model "$model"); fi
echo "soak: $repeat passes of $seq ${model_args[*]} -> $out/run" >&2
start=$(date +%s)
"$exe" run "$seq" --output "$out/run" --repeat "$repeat" "${model_args[@]}" -q
echo "soak: wall time $(( $(date +%s) - start )) s" >&2
python3 - "$out/run" <<'PY'
import csv, json, os, statistics, sys
run = sys.argv[1]
s = json.load(open(os.path.join(run, "summary.json")))
passes = s["passes"]
# Per-pass medians of two stages: ORB extraction does not depend on the map (it measures the
# machine's load), local-map tracking does (it would grow with an unbounded map).
with open(os.path.join(run, "timings.csv")) as f:
    rows = list(csv.DictReader(f))
def stage(k, name):
    size = len(rows) // len(passes)
    values = [float(r[name]) for r in rows[k * size:(k + 1) * size] if name in r]
    return statistics.median(values) if values else float("nan")
print("| pass | frames | tracked | lost | relocalised | tracking median (ms) | ORB extraction (ms) | local-map tracking (ms) | fps | RSS at end (MiB) | keyframes | map points | ATE (m) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for k, p in enumerate(passes):
    ate = f"{p['ate_rmse_m']:.4f}" if "ate_rmse_m" in p else "–"
    print(f"| {p['pass']} | {p['frames']} | {100.0 * p['tracked_frames'] / max(1, p['frames']):.1f} % | "
          f"{p['lost_frames']} | {p['relocalisations']} | {p['tracking_median_ms']:.1f} | "
          f"{stage(k, 'orb_extract_ms'):.1f} | {stage(k, 'track_local_map_ms'):.1f} | "
          f"{p['frames_per_second']:.1f} | {p['rss_end_mib']:.0f} | {p['keyframes_in_map']} | "
          f"{p['points_in_map']} | {ate} |")
n = len(passes)
half = n // 2
def median(key, rows):
    return statistics.median(p[key] for p in rows)
print()
print(f"frames {s['frames']}, peak RSS {s['peak_rss_mib']:.0f} MiB; RSS at the end of pass 1 "
      f"{passes[0]['rss_end_mib']:.0f} MiB, of pass {n} {passes[-1]['rss_end_mib']:.0f} MiB")
if n >= 4:
    growth = (passes[-1]["rss_end_mib"] - passes[half - 1]["rss_end_mib"]) / (n - half)
    print(f"RSS growth over the second half: {growth:+.1f} MiB per pass")
    t1, t2 = median("tracking_median_ms", passes[:half]), median("tracking_median_ms", passes[half:])
    print(f"tracking median, first half {t1:.1f} ms, second half {t2:.1f} ms (ratio {t2 / t1:.2f})")
    def ratio(ks):
        return statistics.median(stage(k, "track_local_map_ms") / stage(k, "orb_extract_ms") for k in ks)
    r1, r2 = ratio(range(half)), ratio(range(half, n))
    print(f"local-map tracking / ORB extraction (load-independent), first half {r1:.2f}, "
          f"second half {r2:.2f}")
if "ate_rmse_m" in s:
    print(f"ATE of the whole stream against the repeated ground truth: {s['ate_rmse_m']:.4f} m")
PY
