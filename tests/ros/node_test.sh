#!/usr/bin/env bash
# `mcslam ros` end to end: roscore on 127.0.0.1 at a free port, the node, and a player that
# publishes a synthetic bag and records what the node publishes. The node's poses must match the
# offline run of the same bag (ATE between them <= 5 mm) and every output topic must appear.
# Everything started here is stopped (process groups), also on failure.
set -euo pipefail
MCSLAM=$1; TOOL=$2; WORK=$3
rm -rf "$WORK"; mkdir -p "$WORK"
fail() { echo "FAIL: $*"; for f in node roscore; do echo "--- $f.log"; tail -20 "$WORK/$f.log" 2>/dev/null || true; done; exit 1; }
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
"$MCSLAM" synth -o "$WORK/seq" --frames $FRAMES --width 320 --height 240 -q
"$MCSLAM" export-bag "$WORK/seq" "$WORK/seq.bag" -q
"$MCSLAM" run "$WORK/seq.bag" -o "$WORK/offline" --sequential -q

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

setsid "$MCSLAM" ros --output "$WORK/node" --sequential --keep-all --cloud-period 0.5 \
  > "$WORK/node.log" 2>&1 &
node=$!
groups+=($node)

# ApproximateTime may hold the last pair back until a newer message arrives: FRAMES - 1.
"$TOOL" play "$WORK/seq.bag" "$WORK/poses.txt" "$WORK/topics.txt" $((FRAMES - 1)) 240 ||
  fail "player failed"

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
for topic in /mcslam/pose /mcslam/path /mcslam/map_points /mcslam/image "/tf:map->camera"; do
  grep -qx -- "$topic" "$WORK/topics.txt" || fail "nothing received on $topic"
done
ate=$("$MCSLAM" eval --gt "$WORK/offline/trajectory_online.txt" --est "$WORK/poses.txt" --json |
  python3 -c 'import json, sys; print(json.load(sys.stdin)["ate_rmse_m"])')
ate_final=$("$MCSLAM" eval --gt "$WORK/offline/trajectory.txt" --est "$WORK/poses.txt" --json |
  python3 -c 'import json, sys; print(json.load(sys.stdin)["ate_rmse_m"])')
echo "published poses: $poses of $FRAMES frames; ATE against the offline run: $ate m (online" \
  "poses), $ate_final m (final trajectory)"
python3 -c "import sys; sys.exit(0 if $ate <= 0.005 else 1)" || fail "ATE $ate m > 5 mm"

# An image the node cannot use (colour message 3 in yuv422): one error, exit 1, and the frames
# received before it processed and written.
"$TOOL" mutate "$WORK/seq.bag" "$WORK/bad.bag" encoding
setsid "$MCSLAM" ros --output "$WORK/node_bad" --sequential --keep-all > "$WORK/node.log" 2>&1 &
node=$!
groups+=($node)
"$TOOL" play "$WORK/bad.bag" "$WORK/poses_bad.txt" "$WORK/topics_bad.txt" 3 30 || fail "player failed"
set +e
wait "$node"
rc=$?
set -e
[ $rc -eq 1 ] || fail "node exit code $rc on a bad image, expected 1"
[ "$(grep -c '^mcslam: error: ' "$WORK/node.log")" -eq 1 ] || fail "not one error line"
grep -q "^mcslam: error: /camera/rgb/image_color: unknown colour encoding 'yuv422'" \
  "$WORK/node.log" || fail "the error does not name the topic and the encoding"
[ "$(grep -vc '^#' "$WORK/node_bad/trajectory.txt")" -eq 3 ] ||
  fail "the 3 frames before the bad image were not all written"
echo "bad image: $(grep '^mcslam: error: ' "$WORK/node.log")"
echo "PASS"
