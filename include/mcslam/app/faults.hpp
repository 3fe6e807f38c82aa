#pragma once
// `mcslam faults`: a copy of a sequence with faults injected, to see how mcslam degrades and
// recovers: dropped frames (every k-th, or a burst), black or saturated colour images, depth all
// zero, a frozen frame repeated, a jump of the timestamps, and a kidnap (black images and no
// depth while the camera keeps moving). Untouched images are listed by their original paths.

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace mcslam::app {

struct Fault {
  enum class Kind {
    kDropEvery,
    kDropBurst,
    kBlack,
    kSaturate,
    kZeroDepth,
    kFreeze,
    kTimeJump,
    kKidnap
  };
  Kind kind = Kind::kDropEvery;
  int start = 0;         ///< first frame (0-based index into the sequence's associated frames)
  int length = 0;        ///< frames affected (kDropEvery: the period k)
  double seconds = 0.0;  ///< kTimeJump: added to every timestamp from `start` on
};

/// Parses "drop-every:K", "drop-burst:START:LEN", "black:START:LEN", "saturate:START:LEN",
/// "zero-depth:START:LEN", "freeze:START:LEN", "time-jump:START:SECONDS", "kidnap:START:LEN";
/// throws InputError naming the text and the expected forms.
Fault parse_fault(const std::string& text);

/// "black:200:15", the form parse_fault() reads.
std::string to_string(const Fault& fault);

struct FaultRequest {
  std::string sequence_dir;
  std::string output_dir;
  std::vector<Fault> faults;
};

/// Writes output_dir as a TUM-layout sequence: rgb.txt, depth.txt (listing new images for the
/// frames a fault changed, the originals otherwise), groundtruth.txt (shifted like the frames
/// after a time jump), camera.yaml (the source's camera, so that the copy needs no folder-name
/// preset), detections.json when the source has one (the boxes follow their frames: none on a
/// blank frame, the frozen frame's boxes while it is repeated, shifted after a time jump) and
/// faults.json (each fault with its frames and time span, for the evaluation).
/// Returns faults.json's content. Throws InputError for bad input (an unreadable sequence, a
/// fault outside the sequence's frames, an output folder that cannot be written).
nlohmann::json write_faulty_sequence(const FaultRequest& request);

}  // namespace mcslam::app
