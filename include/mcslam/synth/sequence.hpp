#pragma once
// A whole synthetic RGB-D sequence: the room scene, the camera path and per-frame rendering, in
// memory (for tests) or written to disk in TUM RGB-D layout (`mcslam synth`).

#include <functional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/core/trajectory.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/synth/objects.hpp"
#include "mcslam/synth/renderer.hpp"
#include "mcslam/synth/scene.hpp"

namespace mcslam::synth {

/// In-memory generation: frames are rendered on demand, no disk I/O. Frame i is at scene time
/// t = i / fps with timestamp 1.0 + t; its noise is seeded from options.seed and t. With
/// options.readout_time > 0 frames are rolling-shutter renders (see SynthOptions::readout_time)
/// and T_w_c(i) is the pose at the middle of the readout.
class SyntheticSequence {
 public:
  /// Throws InputError when options.check() fails.
  explicit SyntheticSequence(const SynthOptions& options);

  int size() const { return static_cast<int>(groundtruth_.size()); }
  double timestamp(int i) const { return groundtruth_.at(i).timestamp; }
  /// Scene time of frame i (timestamp - 1.0).
  double time(int i) const { return i / options_.fps; }
  const SE3& T_w_c(int i) const { return groundtruth_.at(i).T_w_c; }
  RenderedFrame frame(int i) const;
  /// Ground truth of every scene object at frame i (see synth::object_states; the moving flag
  /// compares with frame i - 1's time, i.e. time(i) - 1 / fps). The first form renders frame i;
  /// the second takes frame(i) when it is already rendered.
  std::vector<ObjectState> object_states(int i) const;
  std::vector<ObjectState> object_states(int i, const RenderedFrame& frame) const;
  /// Oracle detections of frame i (frame = frame(i)) with timestamp(i); min_pixels < 0 means
  /// oracle_min_pixels() of the image size (400 at 640 x 480).
  perception::FrameDetections oracle_detections(int i, const RenderedFrame& frame,
                                                int min_pixels = -1) const;
  const Trajectory& groundtruth() const { return groundtruth_; }
  PinholeCamera camera() const { return options_.camera(); }
  const Scene& scene() const { return renderer_.scene(); }
  const Renderer& renderer() const { return renderer_; }
  const SynthOptions& options() const { return options_; }

 private:
  SynthOptions options_;
  Trajectory groundtruth_;
  Renderer renderer_;
};

/// Writes the sequence in TUM layout into `directory` (created if needed): rgb/<t>.png (8-bit
/// BGR), depth/<t>.png (16-bit, metres * 5000, 0 invalid), rgb.txt, depth.txt, groundtruth.txt
/// ("timestamp tx ty tz qx qy qz qw" of T_w_c), and camera.yaml:
///   camera:
///     fx: 525.0
///     fy: 525.0
///     cx: 319.5
///     cy: 239.5
///     width: 640
///     height: 480
///     depth_factor: 5000.0
///     bf: 40.0
///     readout_time: 0.03   (only when options.readout_time > 0)
/// Timestamps are written with 6 decimals.
///
/// detections.json (perception::write_detections, source "synthetic ground truth"): the oracle
/// detections of every frame (SyntheticSequence::oracle_detections with the default min_pixels),
/// one frame per RGB timestamp, with the image size.
///
/// objects.json, only when options.dynamic.enabled (otherwise an objects.json already in the
/// directory is removed): the ground truth of every object per frame
/// (SyntheticSequence::object_states):
///   {
///     "format": "mcslam-synth-objects",
///     "version": 1,
///     "image_width": 640, "image_height": 480,
///     "fps": 30.0,
///     "min_pixels": 400,                       (threshold of detections.json)
///     "objects": [                             (Scene::objects, in label order)
///       {"index": 0, "class": "dining table", "class_id": 60, "motion": "static",
///        "size": [0.8, 1.2, 0.75]},            (box edge lengths along the object's x, y, z)
///       ...
///       {"index": 8, "class": "person", "class_id": 0, "motion": "free", ...},
///       {"index": 9, "class": "chair", "class_id": 56, "motion": "slide", ...}
///     ],                                       (motion: "static", "free" or "slide")
///     "frames": [
///       {"timestamp": 1.000000, "objects": [   (one entry per object, in the same order)
///          {"index": 0, "visible_pixels": 5123, "box": [x, y, width, height], "moving": false,
///           "pose": [tx, ty, tz, qx, qy, qz, qw]},   (T_w_o at the frame's time)
///          ...]},
///       ...
///     ]
///   }
/// where "box" is the bounding rectangle of the object's labelled pixels ([0, 0, 0, 0] when none
/// is visible) and "moving" whether its pose changed since the previous frame by more than 1 mm
/// or 0.1 deg.
///
/// progress(done, total) is called after each frame. Throws InputError on bad options or when the
/// directory or a file cannot be written.
void write_sequence(const std::string& directory, const SynthOptions& options,
                    const std::function<void(int, int)>& progress = {});

}  // namespace mcslam::synth
