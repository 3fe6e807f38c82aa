#!/usr/bin/env bash
# Bad ROS 2 recordings: one clear error naming the file, the topic and the message, exit 1, and
# an earlier run's results in the output folder untouched (a recording is checked whole before
# any frame is processed). The ROS 2 counterpart of tests/ros/bad_bags_test.sh.
set -euo pipefail
export LC_ALL=C  # byte patterns (grep -P) in binary files
MCSLAM=$1; TOOL=$2; WORK=$3
rm -rf "$WORK"; mkdir -p "$WORK"
fail() { echo "FAIL: $*"; exit 1; }

"$MCSLAM" synth -o "$WORK/seq" --frames 12 --width 160 --height 120 -q
"$MCSLAM" export-bag "$WORK/seq" "$WORK/good" --format ros2 -q
"$MCSLAM" export-bag "$WORK/seq" "$WORK/zstd" --format ros2 --compression zstd -q
"$MCSLAM" run "$WORK/good" -o "$WORK/out" --sequential -q 2> /dev/null
before=$(cd "$WORK/out" && md5sum trajectory.txt summary.json status.json timings.csv)
"$MCSLAM" bag-info "$WORK/good" | grep -q "Topic: /camera/rgb/image_color | Type: sensor_msgs/msg/Image | Count: 12" ||
  fail "bag-info does not list the colour topic"
"$MCSLAM" bag-info "$WORK/good" --json | grep -q '"storage_identifier": "mcap"' || fail "bag-info --json"
# bag-info reads ROS 1 bags too (when mcslam is built with ROS).
if "$MCSLAM" export-bag "$WORK/seq" "$WORK/ros1.bag" -q 2> /dev/null; then
  "$MCSLAM" bag-info "$WORK/ros1.bag" |
    grep -q "Topic: /camera/rgb/image_color | Type: sensor_msgs/Image | Count: 12 | Serialization Format: ros1" ||
    fail "bag-info on a ROS 1 bag"
fi

mcap=$WORK/good/good_0.mcap
size=$(stat -c %s "$mcap")
head -c $((size / 2)) "$mcap" > "$WORK/truncated.mcap"
cp "$mcap" "$WORK/badmagic.mcap"; printf 'X' | dd of="$WORK/badmagic.mcap" bs=1 seek=1 conv=notrunc 2> /dev/null
cp "$mcap" "$WORK/crc.mcap"; printf '\x55\xAA' | dd of="$WORK/crc.mcap" bs=1 seek=$((size / 2)) conv=notrunc 2> /dev/null
cp "$WORK/zstd/zstd_0.mcap" "$WORK/undecompressable.mcap"
at=$(grep -obUaP '\x28\xb5\x2f\xfd' "$WORK/undecompressable.mcap" | head -1 | cut -d: -f1)
printf '\x00' | dd of="$WORK/undecompressable.mcap" bs=1 seek="$at" conv=notrunc 2> /dev/null
"$TOOL" sqlite-other "$WORK/notarecording.db3"
echo "this is not a recording" > "$WORK/junk.mcap"
"$TOOL" mutate "$WORK/good" "$WORK/encoding" encoding
"$TOOL" mutate "$WORK/good" "$WORK/stamps" stamps-back
"$TOOL" mutate "$WORK/good" "$WORK/short" short
"$MCSLAM" export-bag "$WORK/seq" "$WORK/sqlite" --format ros2 --storage sqlite3 -q
"$TOOL" mutate "$WORK/sqlite" "$WORK/sqlitestamps" stamps-back

check() {  # name (file or folder in WORK), expected text in the error, extra args...
  local name=$1 expect=$2; shift 2
  local path=$WORK/$name
  [ -e "$path" ] || path=$(ls -d "$WORK/$name".* | head -1)
  set +e
  "$MCSLAM" run "$path" -o "$WORK/out" --sequential -q "$@" 2> "$WORK/$name.err"
  local rc=$?
  set -e
  [ $rc -eq 1 ] || { cat "$WORK/$name.err"; fail "$name: exit $rc, expected 1"; }
  [ "$(wc -l < "$WORK/$name.err")" -eq 1 ] || { cat "$WORK/$name.err"; fail "$name: not one line"; }
  grep -q "^mcslam: error: .*$name" "$WORK/$name.err" || { cat "$WORK/$name.err"; fail "$name: file not named"; }
  grep -qi -- "$expect" "$WORK/$name.err" || { cat "$WORK/$name.err"; fail "$name: no '$expect'"; }
  [ "$(cd "$WORK/out" && md5sum trajectory.txt summary.json status.json timings.csv)" = "$before" ] ||
    fail "$name: the earlier results were changed"
  echo "ok $name: $(cat "$WORK/$name.err")"
}
check truncated "truncated"
check badmagic "bad magic"
check crc "CRC mismatch"
check undecompressable "zstd cannot decompress"
check notarecording "not a ROS 2 recording"
check junk "not an MCAP file"
check good "no topic '/nope' (the recording has: .*/camera/depth/image (sensor_msgs/msg/Image, 12)" --rgb-topic /nope
check encoding "topic '/camera/rgb/image_color' message 3 .*unknown colour encoding 'yuv422'"
check stamps "topic '/camera/rgb/image_color' message 3 .*timestamps go back"
check sqlitestamps "message 3 .*timestamps go back"
check short "topic '/camera/rgb/image_color' message 3.*shorter than its fields"
echo "PASS"
