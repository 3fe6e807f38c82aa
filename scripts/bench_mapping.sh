#!/usr/bin/env bash
# Benchmark of the dense map (docs/mapping.md): how well the occupancy map leaves people out.
#
# Synthetic rooms rendered by `mcslam synth` (exact static geometry known, Kinect-like depth
# noise, ground-truth boxes, --sequential so that each run is deterministic):
#   walk       a person walking through the room
#   four       four people
#   undetected three people, one without a box (it walks in to fill up to 45 % of the view)
#   chair      a chair pushed 1 m across the floor, then left standing (no person)
# each run with the masks (the default) and with mapping.use_masks: false (every pixel a static
# surface, what a map without object knowledge would be). Printed per scene: the ghost rate
# (occupied voxels farther than one voxel from every static surface of the final map, the pushed
# chair counted at its final place), the completeness (static surface voxels seen from 3
# keyframes that are occupied), and for the chair its first place (occupied voxels left there)
# and its final place (share of its seen surface voxels occupied). Read from summary.json
# `occupancy.quality`, which `mcslam run` computes on any sequence of `mcslam synth`.
#
# With ../shared/data (Bonn crowd part1) and a detector model present, also Bonn crowd part1:
# REF = its first 240 frames (no one in view), FULL = the whole of part1, and FULL's occupied
# cells where REF saw free (`mcslam grid-compare`), with the masks and with --no-dynamics;
# threaded runs, RUNS each (the median is printed).
#
# Usage: scripts/bench_mapping.sh [--output DIR] [--frames N] [--runs N] [--no-bonn]
set -euo pipefail
cd "$(dirname "$0")/.."
out=results/bench_mapping
frames=300
runs=3
bonn=1
while [ $# -gt 0 ]; do
  case "$1" in
    --output) out="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --runs) runs="$2"; shift 2 ;;
    --no-bonn) bonn=0; shift ;;
    *) echo "bench_mapping: unknown option $1" >&2; exit 2 ;;
  esac
done
exe=./build/mcslam
[ -x "$exe" ] || { echo "bench_mapping: $exe not found; run scripts/build.sh first" >&2; exit 1; }
mkdir -p "$out/runs"
printf 'mapping:\n  use_masks: false\n' > "$out/no_masks.yaml"

# name: synth options
scenes=(
  "walk:--dynamic --no-chair"
  "four:--dynamic --no-chair --people 4"
  "undetected:--dynamic --no-chair --people 3 --undetected-people 1"
  "chair:--dynamic --no-person --chair-push 1.0"
)
for spec in "${scenes[@]}"; do
  name=${spec%%:*}
  dir="$out/synthetic/$name"
  if [ ! -f "$dir/objects.json" ]; then
    echo "bench_mapping: rendering $name" >&2
    # shellcheck disable=SC2086
    "$exe" synth --output "$dir" --frames "$frames" --seed 1 --depth-noise ${spec#*:} -q
  fi
  for variant in masks no_masks; do
    args=()
    [ "$variant" = no_masks ] && args=(-c "$out/no_masks.yaml")
    run_dir="$out/runs/$name-$variant"
    echo "bench_mapping: $name ($variant)" >&2
    "$exe" run "$dir" --sequential --detections "$dir/detections.json" "${args[@]}" \
      --output "$run_dir" -q 2> "$run_dir.err" || echo "bench_mapping: $run_dir failed" >&2
  done
done

python3 - "$out" <<'EOF'
import json, os, sys
out = sys.argv[1]
def quality(run):
    path = os.path.join(out, "runs", run, "summary.json")
    if not os.path.exists(path):
        return None
    with open(path) as f:
        s = json.load(f)
    return s.get("occupancy", {}).get("quality"), s.get("ate_rmse_m")
print("Synthetic rooms (sequential, ground-truth boxes, Kinect-like depth noise)\n")
print("| scene | ghost rate, masks | ghost rate, no masks | completeness, masks | ATE m | chair's first place: occupied / voxels seen free | chair's final place occupied |")
print("|---|---|---|---|---|---|---|")
for name in ["walk", "four", "undetected", "chair"]:
    a, b = quality(name + "-masks"), quality(name + "-no_masks")
    if not a or not a[0]:
        print(f"| {name} | run failed | | | | | |")
        continue
    q, ate = a
    qn = b[0] if b and b[0] else None
    first = final = ""
    for m in q.get("movers", []):
        fp, fl = m["first_place"], m["final_place"]
        first = f"{fp['occupied']} / {fp['free']} (of {fp['voxels']})"
        final = f"{100 * fl['occupied_ratio']:.1f} % of {fl['surface_seen']}"
    nm = f"{100 * qn['ghost_rate']:.2f} %" if qn else "failed"
    print(f"| {name} | {100 * q['ghost_rate']:.2f} % ({q['ghosts']} of {q['occupied']}) | {nm} | "
          f"{100 * q['completeness']:.1f} % | {ate:.4f} | {first} | {final} |")
EOF

data=../shared/data/bonn/rgbd_bonn_crowd_part1
model=../shared/models/yolov8n_320.onnx
if [ "$bonn" = 1 ] && [ -d "$data" ] && [ -f "$model" ]; then
  for r in $(seq 1 "$runs"); do
    for v in ref full full_nodyn; do
      d="$out/bonn/$v-$r"
      [ -f "$d/summary.json" ] && continue
      case $v in
        ref) extra=(--max-frames 240) ;;
        full) extra=() ;;
        full_nodyn) extra=(--no-dynamics) ;;
      esac
      echo "bench_mapping: Bonn part1 $v run $r" >&2
      "$exe" run "$data" --model "$model" --output "$d" "${extra[@]}" -q
    done
  done
  echo
  echo "Bonn crowd part1 (threaded, yolov8n_320): FULL's occupied cells where REF saw free"
  echo
  echo "| run | with the masks | --no-dynamics | fps (FULL) | mapping ms per keyframe (median, p95) | integration, the final one or rebuild (ms) |"
  echo "|---|---|---|---|---|---|"
  for r in $(seq 1 "$runs"); do
    m=$("$exe" grid-compare "$out/bonn/ref-$r" "$out/bonn/full-$r" --json)
    n=$("$exe" grid-compare "$out/bonn/ref-$r" "$out/bonn/full_nodyn-$r" --json)
    python3 - "$r" "$m" "$n" "$out/bonn/full-$r/summary.json" <<'EOF'
import json, sys
r, m, n, path = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3]), sys.argv[4]
s = json.load(open(path))
o = s["occupancy"]
t = o["time_per_keyframe_ms"]
def fig(j):
    return f"{100 * j['appeared_rate']:.2f} % ({j['appeared']} of {j['full_occupied_seen_by_ref']})"
print(f"| {r} | {fig(m)} | {fig(n)} | {s['frames_per_second']:.1f} | {t['median']:.0f}, {t['p95']:.0f} | "
      f"{o.get('integration', 'live')}, {o['last_rebuild_ms']:.0f} |")
EOF
  done
fi
