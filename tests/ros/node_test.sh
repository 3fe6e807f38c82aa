#!/usr/bin/env bash
# `mcslam ros` end to end: roscore on 127.0.0.1 at a free port, the node, and a player that
# publishes a synthetic bag (a person and a pushed chair, their boxes from the sequence's
# detections.json) and records what the node publishes. Three runs of the node:
#  1. --odom-frame odom, the player broadcasting a constant odom -> camera: the poses match the
#     offline run of the same bag (ATE between them <= 5 mm); every output topic delivers; the
#     grid is latched (a subscriber that connects after the run's last grid still gets it), in
#     frame floor, 0.05 m, with occupied and free cells; /tf_static has map -> floor; map -> odom
#     * odom -> camera is the published pose (<= 1 mm, tests/ros/check_map_odom.py) and no map
#     -> camera is sent.
#  2. an image it cannot use: one error, exit 1, the frames before written; tf map -> camera.
#  3. that bag again with --odom-frame odom but no odom tf, and --no-occupancy: poses but no map
#     -> odom (the failed lookups warned about and counted in summary.json), no map topics; with
#     tracker.pose_filter.lag 1, each frame after the first gives the frame before's lagged pose
#     on /mcslam/pose_lagged, stamped with that frame's stamp.
# Everything started here is stopped (process groups), also on failure.
set -euo pipefail
MCSLAM=$1; TOOL=$2; WORK=$3
rm -rf "$WORK"; mkdir -p "$WORK"
fail() { echo "FAIL: $*"; for f in "$WORK"/*.log; do echo "--- $f"; tail -20 "$f" || true; done; exit 1; }
if ! command -v roscore > /dev/null; then
  if [ "${MCSLAM_STRICT_TESTS:-0}" = 1 ]; then echo "MCSLAM_STRICT_TESTS=1: roscore missing"; exit 1; fi
  echo "SKIP: roscore not installed (scripts/install-deps.sh)"; exit 77
fi

# Processes started here, each the leader of its own group. roscore starts rosmaster and rosout
# in sessions of their own, so the cleanup also stops every descendant it finds.
groups=()
descendants() {
  local p
  for p in $(ps -o pid= --ppid "$1" 2> /dev/null); do
    echo "$p"
    descendants "$p"
  done
}
cleanup() {
  local all=() p alive
  for p in "${groups[@]}"; do all+=("$p" $(descendants "$p")); done
  for p in "${groups[@]}"; do kill -INT -- "-$p" 2> /dev/null || true; done
  for _ in $(seq 1 100); do
    alive=0
    for p in "${all[@]}"; do kill -0 "$p" 2> /dev/null && alive=1; done
    [ $alive -eq 0 ] && return 0
    sleep 0.1
  done
  for p in "${groups[@]}"; do kill -KILL -- "-$p" 2> /dev/null || true; done
  for p in "${all[@]}"; do kill -KILL "$p" 2> /dev/null || true; done
}
trap cleanup EXIT


FRAMES=60
"$MCSLAM" synth -o "$WORK/seq" --frames $FRAMES --width 320 --height 240 --dynamic -q
"$MCSLAM" export-bag "$WORK/seq" "$WORK/seq.bag" -q
BOXES=(--detections "$WORK/seq/detections.json")
"$MCSLAM" run "$WORK/seq.bag" -o "$WORK/offline" --sequential "${BOXES[@]}" -q

PORT=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI=http://127.0.0.1:$PORT ROS_IP=127.0.0.1 ROS_HOSTNAME=127.0.0.1
export ROS_HOME=$WORK/ros_home ROS_LOG_DIR=$WORK/ros_home/log
mkdir -p "$ROS_LOG_DIR"
setsid roscore -p "$PORT" > "$WORK/roscore.log" 2>&1 &
groups+=($!)
for i in $(seq 1 300); do
  python3 -c 'import os, xmlrpc.client; xmlrpc.client.ServerProxy(os.environ["ROS_MASTER_URI"]).getPid("/t")' \
    2> /dev/null && break
  [ "$i" -lt 300 ] || fail "roscore did not come up on port $PORT"
  sleep 0.1
done

# The robot's odometry as the player broadcasts it: odom -> camera as x,y,z,qx,qy,qz,qw (0.3 rad
# about (0.2, 0.9, 0.4)).
ODOM_CAMERA=0.5,-0.2,0.3,0.029739299889,0.133826849502,0.059478599779,0.988771077936
setsid "$MCSLAM" ros --output "$WORK/node" --sequential --keep-all --cloud-period 0.5 \
  --grid-period 0.5 "${BOXES[@]}" --odom-frame odom > "$WORK/node_odom.log" 2>&1 &
node=$!
groups+=($node)

# ApproximateTime may hold the last pair back until a newer message arrives: FRAMES - 1.
"$TOOL" play "$WORK/seq.bag" "$WORK/poses.txt" "$WORK/topics.txt" $((FRAMES - 1)) 240 \
  "$ODOM_CAMERA" "$WORK/map_odom.txt" || fail "player failed"
# The player waited 1.5 s after the last pose: every frame is processed, the map no longer
# changes, and its last grid was sent at most 0.6 s after its last change (--grid-period 0.5 and
# the map thread's 0.1 s tick); nothing more is sent until the node stops. A subscriber that
# connects now gets a grid only if it is latched.
"$TOOL" grid /mcslam/grid 10 > "$WORK/grid.txt" || fail "no latched grid for a late subscriber"

kill -INT "$node"
set +e
wait "$node"
rc=$?
set -e
[ $rc -eq 0 ] || fail "node exit code $rc after SIGINT"
grep -q '"complete"' "$WORK/node/status.json" || fail "node output not complete"
[ -s "$WORK/node/trajectory.txt" ] || fail "node wrote no trajectory"

poses=$(wc -l < "$WORK/poses.txt")
[ "$poses" -ge $((FRAMES - 2)) ] || fail "only $poses poses published"
for topic in /mcslam/pose /mcslam/path /mcslam/map_points /mcslam/image /mcslam/grid \
  /mcslam/occupied_voxels:points /mcslam/people /mcslam/people:deleteall-first \
  /mcslam/people:cube "/tf:map->odom" "/tf_static:map->floor"; do
  grep -qx -- "$topic" "$WORK/topics.txt" || fail "nothing received on $topic"
done
if grep -qx -- "/tf:map->camera" "$WORK/topics.txt"; then fail "map -> camera with an odom frame"; fi
ate=$("$MCSLAM" eval --gt "$WORK/offline/trajectory_online.txt" --est "$WORK/poses.txt" --json |
  python3 -c 'import json, sys; print(json.load(sys.stdin)["ate_rmse_m"])')
ate_final=$("$MCSLAM" eval --gt "$WORK/offline/trajectory.txt" --est "$WORK/poses.txt" --json |
  python3 -c 'import json, sys; print(json.load(sys.stdin)["ate_rmse_m"])')
echo "published poses: $poses of $FRAMES frames; ATE against the offline run: $ate m (online" \
  "poses), $ate_final m (final trajectory)"
python3 -c "import sys; sys.exit(0 if $ate <= 0.005 else 1)" || fail "ATE $ate m > 5 mm"

read -r frame width height resolution occupied free unknown cells < "$WORK/grid.txt"
echo "latched grid: frame $frame, ${width}x$height cells of $resolution m, $occupied occupied," \
  "$free free, $unknown unknown"
[ "$frame" = floor ] || fail "grid frame '$frame', expected floor"
[ "$width" -gt 0 ] && [ "$height" -gt 0 ] && [ "$cells" -eq $((width * height)) ] ||
  fail "grid of ${width}x$height with $cells cells"
[ "$resolution" = 0.05 ] || fail "grid resolution $resolution, expected 0.05"
[ "$occupied" -gt 0 ] && [ "$free" -gt 0 ] || fail "grid without occupied or free cells"
python3 "$(dirname "$0")/check_map_odom.py" "$WORK/poses.txt" "$WORK/map_odom.txt" \
  "$ODOM_CAMERA" "$poses" || fail "map -> odom * odom -> camera is not the pose"
python3 -c 'import json, sys; r = json.load(open(sys.argv[1]))["ros"]; print("summary.json ros:", r)
sys.exit(0 if r["odom_lookup_failures"] == 0 and r["grids_published"] >= 1 else 1)' \
  "$WORK/node/summary.json" || fail "summary.json ros: failed odom lookups, or no grid"

# An image the node cannot use (colour message 3 in yuv422): one error, exit 1, and the frames
# received before it processed and written.
"$TOOL" mutate "$WORK/seq.bag" "$WORK/bad.bag" encoding
setsid "$MCSLAM" ros --output "$WORK/node_bad" --sequential --keep-all > "$WORK/node_bad.log" 2>&1 &
node=$!
groups+=($node)
"$TOOL" play "$WORK/bad.bag" "$WORK/poses_bad.txt" "$WORK/topics_bad.txt" 3 30 || fail "player failed"
set +e
wait "$node"
rc=$?
set -e
[ $rc -eq 1 ] || fail "node exit code $rc on a bad image, expected 1"
[ "$(grep -c '^mcslam: error: ' "$WORK/node_bad.log")" -eq 1 ] || fail "not one error line"
grep -q "^mcslam: error: /camera/rgb/image_color: unknown colour encoding 'yuv422'" \
  "$WORK/node_bad.log" || fail "the error does not name the topic and the encoding"
[ "$(grep -vc '^#' "$WORK/node_bad/trajectory.txt")" -eq 3 ] ||
  fail "the 3 frames before the bad image were not all written"
grep -qx -- "/tf:map->camera" "$WORK/topics_bad.txt" || fail "no tf map -> camera by default"
echo "bad image: $(grep '^mcslam: error: ' "$WORK/node_bad.log")"

# An odom frame without its tf, and no dense map: poses, but neither map -> odom (each failed
# lookup warned about, throttled, and counted) nor map -> camera, and none of the map topics.
printf 'tracker:\n  pose_filter:\n    enabled: true\n    lag: 1\n' > "$WORK/lag.yaml"
setsid "$MCSLAM" ros --output "$WORK/node_no_odom" --sequential --keep-all --odom-frame odom \
  --no-occupancy -c "$WORK/lag.yaml" > "$WORK/node_no_odom.log" 2>&1 &
node=$!
groups+=($node)
"$TOOL" play "$WORK/bad.bag" "$WORK/poses_no_odom.txt" "$WORK/topics_no_odom.txt" 3 30 ||
  fail "player failed"
set +e
wait "$node"
rc=$?
set -e
[ $rc -eq 1 ] || fail "node exit code $rc on a bad image, expected 1"
grep -qx /mcslam/pose "$WORK/topics_no_odom.txt" || fail "no pose without the odom tf"
for topic in "/tf:map->odom" "/tf:map->camera" /mcslam/grid /mcslam/occupied_voxels \
  "/tf_static:map->floor"; do
  if grep -qx -- "$topic" "$WORK/topics_no_odom.txt"; then fail "$topic without odom tf or map"; fi
done
grep -q '^mcslam ros: warning: no tf odom -> camera at ' "$WORK/node_no_odom.log" ||
  fail "no warning"
grep -q '^mcslam ros: 3 of 3 poses had no tf odom -> camera' "$WORK/node_no_odom.log" ||
  fail "the failed lookups are not reported at the end"
python3 -c 'import json, sys; r = json.load(open(sys.argv[1]))["ros"]
sys.exit(0 if r["odom_lookup_failures"] == 3 and r["grids_published"] == 0 else 1)' \
  "$WORK/node_no_odom/summary.json" || fail "summary.json ros: not 3 failed lookups, or a grid"
# Frames 0, 1, 2 tracked (the bad image ends the run, which gives out no last lagged pose): the
# lagged poses of frames 0 and 1.
[ "$(cut -d' ' -f1 "$WORK/poses_no_odom.txt.lagged")" = "$(head -2 "$WORK/poses_no_odom.txt" |
  cut -d' ' -f1)" ] || fail "the lagged poses are not those of frames 0 and 1"
if [ -e "$WORK/poses.txt.lagged" ]; then fail "lagged poses without a lag"; fi
echo "no odom tf: $(grep -c '^mcslam ros: warning: no tf' "$WORK/node_no_odom.log") warning(s);" \
  "$(grep '^mcslam ros: 3 of 3' "$WORK/node_no_odom.log")"
echo "PASS"
