#pragma once
// DIR/report.html of `mcslam bench`: one self-contained page (data and scripts inline) with the
// tables, trajectory and error plots, stage timings, annotated frames and a 3D map view. The
// page's scripts are web/report (bundled at build time into report.js beside the mcslam binary);
// this file gathers the data the page shows, following the schema in web/report/README.md.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "mcslam/app/bench/results.hpp"
#include "mcslam/core/trajectory.hpp"
#include "mcslam/eval/metrics.hpp"

namespace mcslam::app::bench {

/// Ground-truth positions between t0 and t1 (seconds; all when t0 > t1), at most `max_poses`
/// (evenly thinned): {"t": [...], "p": [[x, y, z], ...]}.
nlohmann::json groundtruth_json(const Trajectory& groundtruth, double t0, double t1,
                                std::size_t max_poses = 4000);

/// The estimate of one run for the plots: its associated poses moved into the ground-truth frame
/// by the ATE alignment, with the ATE error of each: {"t", "p", "ate_error_m"}. Without an
/// evaluation (no ground truth) the raw estimate and "ate_error_m": null.
nlohmann::json trajectory_json(const Trajectory& estimate, const eval::EvalReport* report,
                               std::size_t max_poses = 4000);

/// The map of a run (its map.json) for the 3D view: flat point and colour arrays (at most
/// `max_points`, evenly thinned), flat line segments, planes with their hulls, keyframe centres.
/// Throws InputError for a missing or broken file.
nlohmann::json map_json(const std::string& map_json_path, std::size_t max_points = 30000);

/// Up to `count` annotated frames of a run's overlays/ folder, half of them (when there are
/// enough) among the frames where an object was dynamic or constrained (objects.json), the rest
/// spread over the run; re-encoded as JPEG `width` pixels wide, base64.
nlohmann::json overlays_json(const std::string& run_dir, int count, int width = 480);

/// The occupancy grid of a run for the report: its grid.png (base64) and summary.json's
/// `occupancy` (cells, voxels, time per keyframe, memory, the synthetic scene's quality when
/// scored). null when the run has no grid.png (mapping off, or a failed run).
nlohmann::json grid_json(const std::string& run_dir);

/// Standard base64 (RFC 4648) with padding.
std::string base64(const unsigned char* data, std::size_t size);

/// The page: `data` inline as JSON (every '<' escaped, so no text in it can end the script) and
/// the bundled scripts.
std::string report_html(const nlohmann::json& data, const std::string& bundle_js);

}  // namespace mcslam::app::bench
