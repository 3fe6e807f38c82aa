#pragma once
// Where the frames of a run come from: a TUM-layout folder (FolderSource) or, in the optional
// ROS module, a ROS 1 bag (ros::BagSource). `mcslam run` reads every kind the same way.

#include <array>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/trajectory.hpp"
#include "mcslam/io/sequence.hpp"

namespace mcslam::io {

/// What a source itself says about its camera; slam::resolve_run_config weighs it between the
/// preset and the user's settings file.
struct CameraHints {
  /// Settings in mcslam's YAML keys carried by the source (a bag written by `mcslam export-bag`
  /// carries its folder's camera); applied like a folder's camera.yaml.
  std::optional<std::string> settings_yaml;
  std::string settings_name;  ///< for messages, e.g. "run.bag:/mcslam/camera_settings"
  /// Intrinsics from the source (sensor_msgs/CameraInfo): fx, fy, cx, cy, width, height and the
  /// plumb-bob distortion k1 k2 p1 p2 k3. They replace the preset's and the embedded settings'.
  struct Intrinsics {
    double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;
    int width = 0, height = 0;
    std::array<double, 5> distortion{0.0, 0.0, 0.0, 0.0, 0.0};
  };
  std::optional<Intrinsics> intrinsics;
  std::string intrinsics_name;  ///< for messages, e.g. "run.bag:/camera/rgb/camera_info"
};

/// A recorded sequence of RGB-D frames. load() is called from one thread at a time (the run's
/// reader thread), not necessarily the one that opened the source.
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// The path given (folder or file), used in messages and to choose a camera preset by name.
  virtual const std::string& path() const = 0;
  /// Associated frames, sorted by strictly increasing RGB timestamp. The paths name where each
  /// image is (a file, or "bag:topic#message") for messages only.
  virtual const std::vector<FrameEntry>& frames() const = 0;
  /// Frame `index` of frames(): BGR colour and depth in metres. `depth_factor` (raw value per
  /// metre) applies to sources that store raw depth units without saying which. Throws
  /// InputError naming the file and the problem.
  virtual RgbdImages load(std::size_t index, double depth_factor) const = 0;
  /// Ground-truth camera poses T_w_c when the source has them. Throws InputError.
  virtual std::optional<Trajectory> groundtruth() const { return std::nullopt; }
  virtual CameraHints camera_hints() const { return {}; }
  /// Problems that did not stop loading.
  virtual std::vector<std::string> warnings() const { return {}; }
};

/// A TUM-layout folder (see RgbdSequence); ground truth from its groundtruth.txt.
class FolderSource : public FrameSource {
 public:
  explicit FolderSource(RgbdSequence sequence) : sequence_(std::move(sequence)) {}
  static std::shared_ptr<FolderSource> open(const std::string& directory,
                                            const SequenceOptions& options = {}) {
    return std::make_shared<FolderSource>(RgbdSequence::open(directory, options));
  }
  const std::string& path() const override { return sequence_.directory(); }
  const std::vector<FrameEntry>& frames() const override { return sequence_.frames(); }
  RgbdImages load(std::size_t index, double depth_factor) const override;
  std::optional<Trajectory> groundtruth() const override;
  std::vector<std::string> warnings() const override { return sequence_.warnings(); }
  const RgbdSequence& sequence() const { return sequence_; }

 private:
  RgbdSequence sequence_;
};

}  // namespace mcslam::io
