#pragma once
// A whole synthetic RGB-D sequence: the room scene, the camera path and per-frame rendering, in
// memory (for tests) or written to disk in TUM RGB-D layout (`mcslam synth`).

#include <functional>
#include <string>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/core/trajectory.hpp"
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
/// Timestamps are written with 6 decimals. progress(done, total) is called after each frame.
/// Throws InputError on bad options or when the directory or a file cannot be written.
void write_sequence(const std::string& directory, const SynthOptions& options,
                    const std::function<void(int, int)>& progress = {});

}  // namespace mcslam::synth
