#pragma once
// Calibrations of the public RGB-D datasets (640x480, depth factor 5000, bf 40).

#include <optional>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"

namespace mcslam::io {

/// Camera for a sequence folder name: a name containing "freiburg1", "freiburg2", "freiburg3"
/// (TUM RGB-D) or "bonn" (Bonn RGB-D Dynamic), case-insensitively, gives that preset; any other
/// name gives nullopt.
std::optional<PinholeCamera> camera_preset_for_sequence(const std::string& folder_name);

/// Camera of a preset by name: "tum_fr1", "tum_fr2", "tum_fr3" or "bonn" (case-insensitive);
/// nullopt for an unknown name.
std::optional<PinholeCamera> camera_preset(const std::string& preset_name);

/// The camera in mcslam's settings keys (camera.fx, ..., readout_time), as a camera.yaml holds
/// it; `comment` (one line) heads the text.
std::string camera_settings_yaml(const PinholeCamera& camera, const std::string& comment);

/// The names camera_preset() accepts.
std::vector<std::string> camera_preset_names();

}  // namespace mcslam::io
