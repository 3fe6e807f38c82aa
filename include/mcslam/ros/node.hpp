#pragma once
// `mcslam ros`: the full pipeline on a robot's live topics (optional ROS module). The header
// names no ROS type.

#include <cstddef>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "mcslam/app/run.hpp"
#include "mcslam/ros/bag.hpp"
#include "mcslam/ros/node_options.hpp"

namespace mcslam::ros {

/// Runs `request` (a RunRequest for the pipeline and the output folder; its `live`, `on_frame`
/// and `on_end` are set here) on the topics until stop_requested() returns true or the ROS master
/// goes away, then writes the outputs as `mcslam run` does (into request.output_dir; when that is
/// empty into a temporary folder that is removed). Waits for the first CameraInfo unless the
/// camera_info topic is empty. Returns the run's summary. Throws InputError for a master that
/// cannot be reached or images that cannot be used (unknown encoding, wrong size).
nlohmann::json run_node(app::RunRequest request, const NodeOptions& options,
                        const std::function<bool()>& stop_requested);

}  // namespace mcslam::ros
