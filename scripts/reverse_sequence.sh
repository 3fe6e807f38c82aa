#!/usr/bin/env bash
# Writes a TUM-layout copy of a sequence played backwards in time (for testing, e.g. a rolling
# shutter read bottom to top: reversed, a camera whose rows are read top to bottom looks like one
# read bottom to top, a readout time of -r).
# Usage: scripts/reverse_sequence.sh SRC DST
#   Every timestamp t of rgb.txt, depth.txt and groundtruth.txt becomes t_first + t_last - t
#   (t_first, t_last: the first and last colour frames), and each list is sorted again. The image
#   folders are symlinked (absolute paths); camera.yaml is copied when SRC has one. DST must not
#   exist. Keep the camera's name in DST's folder name (freiburg1, bonn, ...) so that mcslam
#   picks the same camera preset.
set -euo pipefail
if [[ $# -ne 2 ]]; then
  echo "usage: $0 SRC DST" >&2
  exit 2
fi
src=$(cd "$1" && pwd)
dst=$2
[[ -f "$src/rgb.txt" && -f "$src/depth.txt" ]] || { echo "$0: $src has no rgb.txt/depth.txt" >&2; exit 1; }
[[ -e "$dst" ]] && { echo "$0: $dst exists" >&2; exit 1; }
mkdir -p "$dst"

# The first and last colour timestamps (comment lines start with #).
read -r t_first t_last < <(awk '!/^#/ && NF >= 2 { if (first == "") first = $1; last = $1 }
                                END { print first, last }' "$src/rgb.txt")

# reverse FILE: header comments kept, every other line's first field mapped, rows sorted by time.
# The arithmetic is done on offsets from the first second so that doubles keep the microseconds.
reverse() {
  local in=$1 out=$2
  grep '^#' "$in" > "$out" || true
  awk -v tf="$t_first" -v tl="$t_last" '
    BEGIN { base = int(tf); a = (tf - base) + (tl - base) }
    !/^#/ && NF >= 2 {
      t = a - ($1 - base)
      $1 = sprintf("%d.%06d", base + int(t), int((t - int(t)) * 1e6 + 0.5))
      print
    }' "$in" | sort -k1,1g >> "$out"
}
reverse "$src/rgb.txt" "$dst/rgb.txt"
reverse "$src/depth.txt" "$dst/depth.txt"
[[ -f "$src/groundtruth.txt" ]] && reverse "$src/groundtruth.txt" "$dst/groundtruth.txt"
for d in rgb depth; do
  [[ -d "$src/$d" ]] && ln -s "$src/$d" "$dst/$d"
done
[[ -f "$src/camera.yaml" ]] && cp "$src/camera.yaml" "$dst/camera.yaml"
echo "$dst: $(grep -vc '^#' "$dst/rgb.txt") colour frames from $t_first to $t_last, reversed"
