# Shared by the scripts that run the mcslam binary on a default sequence (source it after cd-ing
# to the repository root; it defines functions only).

# Exits with a message naming SCRIPT when ./build/mcslam has not been built.
require_mcslam() {
  [ -x ./build/mcslam ] || { echo "$1: ./build/mcslam not found; run scripts/build.sh first" >&2; exit 1; }
}

# Prints the default sequence: freiburg1_rpy from ../shared/data when it is there, otherwise a
# synthetic room (300 frames, Kinect depth noise) rendered once into DIR/synthetic_room.
default_sequence() {
  local seq=../shared/data/tum/rgbd_dataset_freiburg1_rpy
  if [ ! -f "$seq/rgb.txt" ]; then
    seq="$1/synthetic_room"
    [ -f "$seq/rgb.txt" ] || ./build/mcslam synth --output "$seq" --frames 300 --depth-noise -q >&2
  fi
  echo "$seq"
}
