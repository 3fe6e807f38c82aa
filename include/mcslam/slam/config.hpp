#pragma once
// Settings files: mcslam's own keys (camera.fx, orb.num_features, tracker.*, mapper.*,
// system.sequential) and ORB-SLAM2 settings files as users have them (Camera.fx, Camera.k1,
// Camera.bf, DepthMapFactor, ThDepth, ORBextractor.nFeatures, ...). Unknown keys are an error.

#include <optional>
#include <string>

#include "mcslam/core/camera.hpp"
#include "mcslam/io/config_file.hpp"
#include "mcslam/io/frame_source.hpp"
#include "mcslam/slam/options.hpp"

namespace mcslam::slam {

struct RunConfig {
  PinholeCamera camera;
  SystemOptions options;
  /// Where the camera came from, e.g. "preset tum_fr1 (folder name)" or a file path.
  std::string camera_source;
};

/// Reads every known key of `file` into camera and options; throws InputError naming the file
/// for unknown keys, wrong types and invalid values.
void apply_config(io::ConfigFile& file, PinholeCamera& camera, SystemOptions& options);

/// The configuration for a sequence: the camera preset chosen by the folder name, then
/// SEQ_DIR/camera.yaml if present, then the user's settings file (each overriding the last).
/// Throws InputError when no camera can be determined or a file is invalid.
RunConfig resolve_run_config(const std::string& sequence_dir,
                             const std::optional<std::string>& settings_path);
/// The same for any source (a folder or a bag file): the preset named by `preset_name`
/// (--camera-preset) or else chosen by the source's file or folder name, then camera.yaml in a
/// folder, then the source's own settings and intrinsics (`hints`: a bag's embedded camera
/// settings and its CameraInfo), then the user's settings file. Throws InputError for an unknown
/// preset, invalid values, or when no camera can be determined.
RunConfig resolve_run_config(const std::string& source_path,
                             const std::optional<std::string>& settings_path,
                             const io::CameraHints& hints,
                             const std::optional<std::string>& preset_name);

/// The effective configuration in mcslam's own YAML keys (it loads back with apply_config).
std::string to_yaml(const RunConfig& config);
/// The same, after a run: with `camera.readout_time: auto`, a comment on that line gives the
/// readout time used and how it was estimated.
std::string to_yaml(const RunConfig& config, const ReadoutReport& readout);

}  // namespace mcslam::slam
