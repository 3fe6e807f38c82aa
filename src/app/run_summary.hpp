#pragma once
// The sections of `mcslam run`'s summary.json made from the run's recorders and its System
// (private to run.cpp): each function turns one part of the run into JSON.

#include <cstddef>
#include <nlohmann/json.hpp>
#include <string>

#include "mcslam/slam/config.hpp"
#include "mcslam/slam/readout_calibration.hpp"
#include "mcslam/slam/system.hpp"
#include "run_observers.hpp"

namespace mcslam::app {

/// The rolling-shutter readout time used and, when estimated, how (summary.json "readout").
nlohmann::json readout_json(const slam::ReadoutReport& r);

/// The calibration pass before the run ("readout" / "calibration").
nlohmann::json calibration_json(const slam::ReadoutCalibration& c);

/// Loops: counts, every verified candidate with its figures, timings ("loops").
nlohmann::json loops_json(const slam::LoopStatistics& stats, const slam::PlaceOptions& place);

/// Frames, tracked and lost frames, relocalisations ("frames" ... "relocalisation").
void add_tracking_figures(nlohmann::json& summary, const FrameRecorder& recorder,
                          std::size_t processed);

/// Failed solves per solver ("solver_failures").
nlohmann::json solver_failures_json(const slam::SolverStatistics& solver);

/// Median, mean and maximum of each per-frame count ("per_frame_counts").
nlohmann::json per_frame_counts_json(const FrameRecorder& recorder);

/// The boxes' source and what was made of them ("dynamics"); `wall_s` gives the detector's rate.
nlohmann::json dynamics_json(const ObjectsRecorder& objects, const slam::System& system,
                             const slam::RunConfig& config,
                             const std::string& detection_description, double wall_s);

/// Frames offered, processed and dropped, and the latency of a real-time run ("realtime").
nlohmann::json realtime_json(const FrameRecorder& recorder, std::size_t offered,
                             std::size_t processed, std::size_t dropped);
/// The lagged pose (tracker.pose_filter.lag > 0, "lagged_pose"): the lag, the poses given out,
/// and how far behind their frames' times they were given out (median, p95).
nlohmann::json lagged_pose_json(const FrameRecorder& recorder, int lag, std::size_t poses);

/// Each tracking stage's times, the per-frame total and the image loads ("stages").
nlohmann::json stages_json(const FrameRecorder& recorder);

/// Each mapping stage's times per keyframe on the mapper's thread ("mapper_stages").
nlohmann::json mapper_stages_json(const slam::System& system);

}  // namespace mcslam::app
