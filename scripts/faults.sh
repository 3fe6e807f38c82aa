#!/usr/bin/env bash
# The fault table: injects each fault into a copy of a sequence (`mcslam faults`), runs mcslam on
# it, and prints per fault the frames tracked and lost, relocalisations, the ATE of the whole run
# and the ATE of the poses after the fault (that segment aligned on its own). Needs a build.
# A sequence with its own detections.json (a synthetic scene's ground-truth boxes, or the output
# of `mcslam detect`) is run with those boxes, which the copies carry through the faults.
# Usage: scripts/faults.sh [--sequential] [--output DIR] [SEQUENCE_DIR]
# (default: ../shared/data/tum/rgbd_dataset_freiburg1_rpy, else a synthetic room it renders)
set -euo pipefail
cd "$(dirname "$0")/.."
out=results/faults
mode=--threaded
seq=""
while [ $# -gt 0 ]; do
  case "$1" in
    --output) out="$2"; shift 2 ;;
    --sequential) mode=--sequential; shift ;;
    *) seq="$1"; shift ;;
  esac
done
source scripts/common.sh
require_mcslam faults
exe=./build/mcslam
mkdir -p "$out"
[ -n "$seq" ] || seq=$(default_sequence "$out")
n=$(grep -vc '^#' "$seq/rgb.txt")
mid=$((n / 2))
faults=(none "drop-every:5" "drop-burst:$mid:10" "black:$mid:15" "saturate:$mid:15"
        "zero-depth:$mid:15" "freeze:$mid:15" "time-jump:$mid:2" "kidnap:$mid:30")
rows=()
for fault in "${faults[@]}"; do
  name=${fault//:/_}
  copy="$out/data/$name"
  rm -rf "$copy" "$out/runs/$name"
  fault_args=()
  [ "$fault" = none ] || fault_args=(--fault "$fault")
  "$exe" faults "$seq" --output "$copy" "${fault_args[@]}" -q
  echo "faults: $fault" >&2
  box_args=()
  [ -f "$copy/detections.json" ] && box_args=(--detections "$copy/detections.json")
  if "$exe" run "$copy" --output "$out/runs/$name" "$mode" "${box_args[@]}" -q \
       2> "$out/runs_$name.err"; then
    rows+=("$name")
  else
    echo "faults: $fault: run FAILED ($(tail -1 "$out/runs_$name.err"))" >&2
    rows+=("$name")
  fi
done
python3 - "$out" "$exe" "${rows[@]}" <<'PY'
import json, os, subprocess, sys
out, exe, names = sys.argv[1], sys.argv[2], sys.argv[3:]
print("| fault | frames | tracked | lost | relocalised | ATE whole run (m) | ATE after the fault (m) |")
print("|---|---|---|---|---|---|---|")
for name in names:
    run = os.path.join(out, "runs", name)
    fault = name.replace("_", ":") if name != "none" else "none"
    try:
        s = json.load(open(os.path.join(run, "summary.json")))
    except OSError:
        print(f"| {fault} | run failed: {open(os.path.join(out, 'runs_' + name + '.err')).read().strip()[-200:]} | | | | | |")
        continue
    faults = json.load(open(os.path.join(out, "data", name, "faults.json")))["faults"]
    t_end = max([f.get("t_end", 0) for f in faults] + [0]) if name != "none" else 0
    after = "–"
    traj = [l for l in open(os.path.join(run, "trajectory.txt")) if l.strip() and not l.startswith("#")]
    seg = [l for l in traj if float(l.split()[0]) > t_end + 1.0]
    if t_end > 0 and len(seg) > 10:
        path = os.path.join(run, "after_fault.txt")
        open(path, "w").writelines(seg)
        r = subprocess.run([exe, "eval", "--gt", os.path.join(out, "data", name, "groundtruth.txt"),
                            "--est", path, "--json"], capture_output=True, text=True)
        if r.returncode == 0:
            after = f"{json.loads(r.stdout)['ate_rmse_m']:.4f}"
    ate = f"{s['ate_rmse_m']:.4f}" if "ate_rmse_m" in s else "–"
    print(f"| {fault} | {s['frames']} | {100 * s['tracked_ratio']:.1f} % | {s['lost_frames']} | "
          f"{s['relocalisations']} | {ate} | {after} |")
PY
