// The sections of `mcslam run`'s summary.json (run_summary.hpp).
#include "run_summary.hpp"

#include <map>
#include <vector>

#include "mcslam/core/timing.hpp"
#include "mcslam/optim/pose_filter.hpp"

namespace mcslam::app {
namespace {

/// A stage's median, 95th percentile and mean time over the frames it ran on.
nlohmann::json stage_stats_json(const SampleStats& s) {
  return {{"median_ms", s.median}, {"p95_ms", s.p95}, {"mean_ms", s.mean}, {"frames", s.count}};
}

}  // namespace

nlohmann::json readout_json(const slam::ReadoutReport& r) {
  nlohmann::json j = {{"mode", r.automatic ? "auto" : "fixed"}, {"readout_time_s", r.readout_time}};
  if (!r.automatic) return j;
  j["estimate_s"] = r.estimate;
  j["std_s"] = r.std;
  j["frames_used"] = r.frames_used;
  j["frames_rejected"] = r.frames_rejected;
  j["epochs"] = r.epochs;
  j["confident"] = r.confident;
  j["confident_at_timestamp"] = r.confident_at;
  j["frames_used_when_confident"] = r.frames_used_when_confident;
  return j;
}

nlohmann::json calibration_json(const slam::ReadoutCalibration& c) {
  return {{"frames", c.frames},
          {"sequence_s", c.sequence_s},
          {"wall_ms", c.wall_ms},
          {"confident", c.report.confident},
          {"estimate_s", c.report.estimate},
          {"std_s", c.report.std},
          {"frames_used", c.report.frames_used},
          {"start_readout_time_s", c.readout_time}};
}

nlohmann::json loops_json(const slam::LoopStatistics& stats, const slam::PlaceOptions& place) {
  nlohmann::json events = nlohmann::json::array();
  int accepted = 0;
  for (const auto& e : stats.events) {
    accepted += e.accepted ? 1 : 0;
    nlohmann::json j = {{"keyframe", e.keyframe},
                        {"matched_keyframe", e.matched},
                        {"timestamp", e.timestamp},
                        {"matched_timestamp", e.matched_timestamp},
                        {"score", e.score},
                        {"matches", e.matches},
                        {"ransac_inliers", e.ransac_inliers},
                        {"inliers", e.inliers},
                        {"accepted", e.accepted},
                        {"verify_ms", e.verify_ms}};
    if (e.accepted) {
      j["correction_m"] = e.correction_m;
      j["correction_deg"] = e.correction_deg;
      j["fused_points"] = e.fused_points;
      j["correct_ms"] = e.correct_ms;
    } else {
      j["reason"] = e.reason;
    }
    events.push_back(std::move(j));
  }
  const SampleStats detection = compute_stats(stats.detection_ms);
  const SampleStats ba = compute_stats(stats.full_ba_ms);
  return {{"enabled", place.loop.enabled && !place.vocabulary.empty()},
          {"vocabulary", place.vocabulary},
          {"candidates_without_matches", stats.unmatched_candidates},
          {"detected", stats.events.size()},
          {"accepted", accepted},
          {"rejected", static_cast<int>(stats.events.size()) - accepted},
          {"detection_median_ms", detection.median},
          {"detection_p95_ms", detection.p95},
          {"keyframes_checked", detection.count},
          {"full_ba_runs", stats.full_ba_runs},
          {"full_ba_aborted", stats.full_ba_aborted},
          {"full_ba_median_ms", ba.median},
          {"events", events}};
}

void add_tracking_figures(nlohmann::json& summary, const FrameRecorder& recorder,
                          std::size_t processed) {
  summary["frames"] = processed;
  summary["tracked_frames"] = recorder.tracked;
  summary["tracked_ratio"] =
      processed == 0 ? 0.0 : static_cast<double>(recorder.tracked) / processed;
  summary["lost_frames"] = recorder.lost;
  summary["not_initialized_frames"] =
      static_cast<int>(processed) - recorder.tracked - recorder.lost;
  summary["relocalisations"] = recorder.relocalised;
  const SampleStats q = compute_stats(recorder.reloc_query_ms);
  summary["relocalisation"] = {
      {"attempts", recorder.reloc_attempts},  {"succeeded", recorder.relocalised},
      {"from_last_pose", recorder.recovered}, {"by_database", recorder.reloc_by_database},
      {"query_median_ms", q.median},          {"query_p95_ms", q.p95},
      {"events", recorder.reloc_events}};
  // The pose filter's outcomes over the tracked frames (optim/pose_filter.hpp).
  using optim::FilterOutcome;
  nlohmann::json filter = nlohmann::json::object();
  for (const FilterOutcome o :
       {FilterOutcome::kFused, FilterOutcome::kDownweighted, FilterOutcome::kHeld,
        FilterOutcome::kRestarted, FilterOutcome::kOff})
    filter[optim::to_string(o)] = recorder.online_poses.count(o) ? recorder.online_poses.at(o) : 0;
  summary["pose_filter"] = filter;
}

nlohmann::json solver_failures_json(const slam::SolverStatistics& solver) {
  return {{"pose", solver.pose_failures},
          {"bundle_adjustment", solver.bundle_adjustment_failures},
          {"full_ba", solver.full_ba_failures},
          {"pose_graph", solver.pose_graph_failures}};
}

nlohmann::json per_frame_counts_json(const FrameRecorder& recorder) {
  nlohmann::json per_frame = nlohmann::json::object();
  for (const auto& [name, samples] : recorder.counts) {
    const SampleStats st = compute_stats(samples);
    per_frame[name] = {{"median", st.median}, {"mean", st.mean}, {"max", st.max}};
  }
  return per_frame;
}

nlohmann::json dynamics_json(const ObjectsRecorder& objects, const slam::System& system,
                             const slam::RunConfig& config,
                             const std::string& detection_description, double wall_s) {
  nlohmann::json d;
  d["source"] = detection_description.empty() ? "none (geometry only)" : detection_description;
  d["enabled"] = config.options.tracker.dynamics.enabled && !detection_description.empty();
  d["constraints"] = config.options.tracker.dynamics.constraints;
  d["frames_with_boxes"] = objects.frames_with_boxes;
  d["fresh_frames"] = objects.fresh_frames;
  d["fresh_ratio"] = objects.frames_with_boxes == 0
                         ? 0.0
                         : static_cast<double>(objects.fresh_frames) / objects.frames_with_boxes;
  d["median_age_frames"] = compute_stats(objects.detection_age).median;
  const SampleStats det = compute_stats(objects.detect_ms);
  d["detector_ms"] = {{"median", det.median}, {"p95", det.p95}, {"count", det.count}};
  d["object_frames"] = objects.object_states;  // box-frames per state
  // Boxes carried forward against the detector's next boxes (see ObjectOutputs).
  d["propagation"] = {{"enabled", config.options.tracker.dynamics.propagate_boxes},
                      {"measured", objects.propagation_iou.size()},
                      {"iou_median", compute_stats(objects.propagation_iou).median},
                      {"stale_iou_median", compute_stats(objects.stale_iou).median}};
  d["mover_frames"] = objects.mover_frames;  // frames where motion without a box was found
  // Every forward pass of a model, whichever frame used its boxes: the detector's actual rate.
  // (none for boxes from a file)
  const std::vector<double> passes_ms = system.detection_source()
                                            ? system.detection_source()->pass_times_ms()
                                            : std::vector<double>{};
  if (!passes_ms.empty()) {
    const SampleStats pass = compute_stats(passes_ms);
    d["detector_passes"] = passes_ms.size();
    d["detector_rate_hz"] = wall_s > 0.0 ? passes_ms.size() / wall_s : 0.0;
    d["detector_pass_ms"] = {{"median", pass.median}, {"p95", pass.p95}};
  }
  return d;
}

nlohmann::json realtime_json(const FrameRecorder& recorder, std::size_t offered,
                             std::size_t processed, std::size_t dropped) {
  const SampleStats latency = compute_stats(recorder.latency_ms);
  nlohmann::json out = {
      {"enabled", true},
      {"frames_offered", offered},
      {"frames_processed", processed},
      {"frames_dropped", dropped},
      {"processed_ratio", offered == 0 ? 0.0 : static_cast<double>(processed) / offered},
      // Tracked frames over the frames the camera delivered: dropped frames count as missing.
      {"coverage", offered == 0 ? 0.0 : static_cast<double>(recorder.tracked) / offered},
      {"latency_median_ms", latency.median},
      {"latency_p95_ms", latency.p95},
      {"latency_max_ms", latency.max}};
  if (!recorder.lagged_latency_ms.empty()) {
    // The lagged pose's: its frame's time to the moment it was given out.
    const SampleStats lagged = compute_stats(recorder.lagged_latency_ms);
    out["lagged_latency_median_ms"] = lagged.median;
    out["lagged_latency_p95_ms"] = lagged.p95;
  }
  return out;
}

nlohmann::json lagged_pose_json(const FrameRecorder& recorder, int lag, std::size_t poses) {
  const SampleStats delay = compute_stats(recorder.lagged_delay_ms);
  return {{"lag_frames", lag},
          {"poses", poses},
          {"delay_median_ms", delay.median},
          {"delay_p95_ms", delay.p95}};
}

nlohmann::json stages_json(const FrameRecorder& recorder) {
  nlohmann::json stages = nlohmann::json::object();
  for (const auto& name : recorder.stage_table.names) {
    // Stages that did not run on a frame count as 0 there only for the per-frame total.
    const auto samples = recorder.stage_samples.find(name);
    stages[name] = stage_stats_json(compute_stats(
        samples == recorder.stage_samples.end() ? std::vector<double>{} : samples->second));
  }
  stages["tracking_total"] = stage_stats_json(compute_stats(recorder.tracking_ms));
  stages["image_load"] = stage_stats_json(compute_stats(recorder.load_ms));
  return stages;
}

nlohmann::json mapper_stages_json(const slam::System& system) {
  std::map<std::string, std::vector<double>> mapper_samples;
  for (const auto& t : system.mapper_times())
    for (const auto& [name, ms] : t.stages) mapper_samples[name].push_back(ms);
  nlohmann::json mapper = nlohmann::json::object();
  for (const auto& [name, samples] : mapper_samples) {
    const SampleStats s = compute_stats(samples);
    mapper[name] = {{"median_ms", s.median}, {"p95_ms", s.p95}, {"keyframes", s.count}};
  }
  return mapper;
}

}  // namespace mcslam::app
