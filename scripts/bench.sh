#!/usr/bin/env bash
# Accuracy and speed benchmark: runs mcslam N times on each sequence, in sequential mode
# (deterministic; accuracy) and threaded mode (the default; speed), and prints a Markdown table of
# medians. With --ablation it also runs the feature combinations points; points+lines;
# points+planes; points+lines+planes (threaded, the default mode, whose runs differ; sequential
# runs are deterministic and would repeat one figure) and prints a second table. Needs a build
# (scripts/build.sh).
# Usage: scripts/bench.sh [--runs N] [--output DIR] [--ablation] [SEQUENCE_DIR ...]
# Without sequences: TUM freiburg1_rpy from ../shared/data (when present) and two synthetic
# sequences rendered into DIR/synthetic (a textured room, and a low-texture one).
set -euo pipefail
cd "$(dirname "$0")/.."
runs=3
out=results/bench
ablation=0
seqs=()
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) runs="$2"; shift 2 ;;
    --output) out="$2"; shift 2 ;;
    --ablation) ablation=1; shift ;;
    *) seqs+=("$1"); shift ;;
  esac
done
exe=./build/mcslam
[ -x "$exe" ] || { echo "bench: $exe not found; run scripts/build.sh first" >&2; exit 1; }
mkdir -p "$out"
if [ ${#seqs[@]} -eq 0 ]; then
  real=../shared/data/tum/rgbd_dataset_freiburg1_rpy
  [ -f "$real/rgb.txt" ] && seqs+=("$real")
  for kind in rich low; do
    dir="$out/synthetic/synthetic_room_$kind"
    if [ ! -f "$dir/rgb.txt" ]; then
      "$exe" synth --output "$dir" --frames 300 --texture "$kind" --depth-noise -q
    fi
    seqs+=("$dir")
  done
fi

for seq in "${seqs[@]}"; do
  name=$(basename "$seq")
  for mode in sequential threaded; do
    for i in $(seq 1 "$runs"); do
      dir="$out/runs/$name/$mode-$i"
      mkdir -p "$out/runs/$name"
      echo "bench: $name $mode run $i/$runs" >&2
      if ! "$exe" run "$seq" --output "$dir" --"$mode" -q 2> "$dir.err"; then
        echo "bench: run failed, see $dir.err" >&2
      fi
    done
  done
done

ablation_configs=(points points,lines points,planes points,lines,planes)
if [ "$ablation" = 1 ]; then
  for seq in "${seqs[@]}"; do
    name=$(basename "$seq")
    for features in "${ablation_configs[@]}"; do
      for i in $(seq 1 "$runs"); do
        dir="$out/ablation/$name/${features//,/+}-$i"
        mkdir -p "$out/ablation/$name"
        echo "bench: $name ablation $features run $i/$runs" >&2
        if ! "$exe" run "$seq" --output "$dir" --threaded --features "$features" -q \
            2> "$dir.err"; then
          echo "bench: run failed, see $dir.err" >&2
        fi
      done
    done
  done
fi

python3 - "$out" "$runs" "$ablation" "${seqs[@]}" <<'PY'
import json, os, statistics, sys
out, runs, ablation, seqs = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1", sys.argv[4:]
def med(xs): return statistics.median(xs) if xs else float('nan')
rows = []
for seq in seqs:
    name = os.path.basename(os.path.normpath(seq))
    for mode in ("sequential", "threaded"):
        s = []
        for i in range(1, runs + 1):
            p = os.path.join(out, "runs", name, f"{mode}-{i}", "summary.json")
            if os.path.exists(p):
                s.append(json.load(open(p)))
        if not s:
            rows.append(f"| {name} | {mode} | 0/{runs} runs | | | | | | |")
            continue
        ate = [x["ate_rmse_m"] for x in s if "ate_rmse_m" in x]
        rpe = [x["eval"]["rpe_time_trans_rmse_m"] for x in s if "eval" in x and "rpe_time_trans_rmse_m" in x["eval"]]
        cov = [x["tracked_ratio"] for x in s]
        trk = [x["stages"]["tracking_total"]["median_ms"] for x in s]
        p95 = [x["stages"]["tracking_total"]["p95_ms"] for x in s]
        fps = [x["frames_per_second"] for x in s]
        mem = [x["peak_rss_mib"] for x in s]
        ate_txt = f"{med(ate):.4f} ({min(ate):.4f}-{max(ate):.4f})" if ate else "n/a"
        rpe_txt = f"{med(rpe):.4f}" if rpe else "n/a"
        rows.append(f"| {name} | {mode} | {len(s)}/{runs} | {ate_txt} | {rpe_txt} | {100*med(cov):.1f} | "
                    f"{med(trk):.1f} / {med(p95):.1f} | {med(fps):.1f} | {med(mem):.0f} |")
table = ["| sequence | mode | runs | ATE RMSE m, median (min-max) | RPE 1 s trans m | tracked % | tracking ms median / p95 | fps | peak MiB |",
         "|---|---|---|---|---|---|---|---|---|"] + rows
text = "\n".join(table) + "\n"
if ablation:
    def stage(x, name):
        st = x["stages"].get(name)
        return st["median_ms"] if st else None
    arows = []
    for seq in seqs:
        name = os.path.basename(os.path.normpath(seq))
        for features in ("points", "points,lines", "points,planes", "points,lines,planes"):
            s = []
            for i in range(1, runs + 1):
                p = os.path.join(out, "ablation", name, features.replace(",", "+") + f"-{i}", "summary.json")
                if os.path.exists(p):
                    s.append(json.load(open(p)))
            label = features.replace(",", "+")
            if not s:
                arows.append(f"| {name} | {label} | 0/{runs} runs | | | | | |")
                continue
            ate = [x["ate_rmse_m"] for x in s if "ate_rmse_m" in x]
            cov = [x["tracked_ratio"] for x in s]
            trk = [x["stages"]["tracking_total"]["median_ms"] for x in s]
            lin = [v for v in (stage(x, "line_extract") for x in s) if v is not None]
            pla = [v for v in (stage(x, "plane_extract") for x in s) if v is not None]
            ate_txt = f"{med(ate):.4f} ({min(ate):.4f}-{max(ate):.4f})" if ate else "n/a"
            arows.append(f"| {name} | {label} | {len(s)}/{runs} | {ate_txt} | {100*med(cov):.1f} | {med(trk):.1f} | "
                         + (f"{med(lin):.1f}" if lin else "-") + " | " + (f"{med(pla):.1f}" if pla else "-") + " |")
    text += "\n" + "\n".join(["| sequence | features | runs | ATE RMSE m, median (min-max) | tracked % | tracking ms median | lines ms | planes ms |",
                               "|---|---|---|---|---|---|---|---|"] + arows) + "\n"
print(text)
open(os.path.join(out, "table.md"), "w").write(text)
PY
