#!/usr/bin/env bash
# Bad bags: one clear error naming the bag and the problem, exit 1, and an earlier run's results
# in the output folder untouched (a bag is checked whole before any frame is processed).
set -euo pipefail
MCSLAM=$1; TOOL=$2; WORK=$3
rm -rf "$WORK"; mkdir -p "$WORK"
fail() { echo "FAIL: $*"; exit 1; }

"$MCSLAM" synth -o "$WORK/seq" --frames 12 --width 160 --height 120 -q
"$MCSLAM" export-bag "$WORK/seq" "$WORK/good.bag" -q
"$MCSLAM" run "$WORK/good.bag" -o "$WORK/out" --sequential -q
before=$(cd "$WORK/out" && md5sum trajectory.txt summary.json status.json timings.csv)

size=$(stat -c %s "$WORK/good.bag")
head -c $((size / 2)) "$WORK/good.bag" > "$WORK/truncated.bag"
echo "this is not a bag" > "$WORK/notabag.bag"
"$TOOL" mutate "$WORK/good.bag" "$WORK/encoding.bag" encoding
"$TOOL" mutate "$WORK/good.bag" "$WORK/depthsize.bag" depth-size
"$TOOL" mutate "$WORK/good.bag" "$WORK/stamps.bag" stamps-back

check() {  # name, expected text in the error, extra args...
  local name=$1 expect=$2; shift 2
  set +e
  "$MCSLAM" run "$WORK/$name.bag" -o "$WORK/out" --sequential -q "$@" 2> "$WORK/$name.err"
  local rc=$?
  set -e
  [ $rc -eq 1 ] || fail "$name: exit $rc, expected 1"
  [ "$(wc -l < "$WORK/$name.err")" -eq 1 ] || { cat "$WORK/$name.err"; fail "$name: not one line"; }
  grep -q "^mcslam: error: .*$name.bag" "$WORK/$name.err" || fail "$name: bag not named"
  grep -qi -- "$expect" "$WORK/$name.err" || { cat "$WORK/$name.err"; fail "$name: no '$expect'"; }
  [ "$(cd "$WORK/out" && md5sum trajectory.txt summary.json status.json timings.csv)" = "$before" ] ||
    fail "$name: the earlier results were changed"
  echo "ok $name: $(cat "$WORK/$name.err")"
}
check truncated "not a readable ROS 1 bag"
check notabag "not a readable ROS 1 bag"
check good "no topic '/nope'" --rgb-topic /nope
check encoding "unknown colour encoding 'yuv422'"
check depthsize "depth images"
check stamps "timestamps go back"
echo "PASS"
