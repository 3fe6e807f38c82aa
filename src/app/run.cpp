#include "mcslam/app/run.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>

#include "mcslam/core/error.hpp"
#include "mcslam/eval/bonn.hpp"
#include "mcslam/eval/metrics.hpp"
#include "mcslam/io/files.hpp"
#include "mcslam/io/sequence.hpp"
#include "mcslam/io/trajectory_io.hpp"
#include "mcslam/map/export.hpp"
#include "mcslam/slam/config.hpp"
#include "mcslam/slam/system.hpp"

namespace mcslam::app {
namespace {

/// Peak resident memory of this process in MiB (Linux), 0 when unknown.
double peak_rss_mib() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
  return 0.0;
}

bool is_bonn(const std::string& directory) {
  std::string name = std::filesystem::path(directory).lexically_normal().filename().string();
  std::transform(name.begin(), name.end(), name.begin(), ::tolower);
  return name.find("bonn") != std::string::npos;
}

class ProgressBar {
 public:
  ProgressBar(bool enabled, std::size_t total) : enabled_(enabled), total_(total) {}
  void update(std::size_t done, double fps, int lost) {
    if (!enabled_ || (done % 5 != 0 && done != total_)) return;
    const int width = 30;
    const int filled = total_ == 0 ? width : static_cast<int>(width * done / total_);
    std::fprintf(stderr, "\r[%s%s] %zu/%zu  %.1f fps  lost %d ", std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), done, total_, fps, lost);
    if (done == total_) std::fputc('\n', stderr);
    std::fflush(stderr);
  }

 private:
  bool enabled_;
  std::size_t total_;
};

std::string format_tum_keyframes(const Trajectory& keyframes) {
  std::ostringstream s;
  s << "# keyframe poses T_w_c: timestamp tx ty tz qx qy qz qw\n";
  s << std::fixed;
  for (const auto& p : keyframes) {
    const auto& q = p.T_w_c.quaternion();
    const auto& t = p.T_w_c.translation();
    s << std::setprecision(6) << p.timestamp << std::setprecision(9) << ' ' << t.x() << ' ' << t.y()
      << ' ' << t.z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
  }
  return s.str();
}

}  // namespace

void apply_feature_list(const std::string& list, bool& points, bool& lines, bool& planes) {
  points = lines = planes = false;
  std::stringstream stream(list);
  for (std::string kind; std::getline(stream, kind, ',');) {
    if (kind == "points")
      points = true;
    else if (kind == "lines")
      lines = true;
    else if (kind == "planes")
      planes = true;
    else
      throw InputError("--features: unknown feature kind '" + kind +
                       "' (use a comma-separated subset of points,lines,planes)");
  }
  if (!points && !lines && !planes)
    throw InputError("--features: name at least one of points, lines, planes");
}

nlohmann::json run_sequence(const RunRequest& request) {
  namespace fs = std::filesystem;
  io::SequenceOptions seq_options;
  if (request.associations_path) seq_options.associations_file = *request.associations_path;
  const io::RgbdSequence sequence = io::RgbdSequence::open(request.sequence_dir, seq_options);
  for (const auto& warning : sequence.warnings())
    std::cerr << "mcslam: warning: " << warning << "\n";
  slam::RunConfig config = slam::resolve_run_config(request.sequence_dir, request.config_path);
  if (request.sequential) config.options.sequential = *request.sequential;
  if (request.features)
    apply_feature_list(*request.features, config.options.use.points, config.options.use.lines,
                       config.options.use.planes);
  io::ensure_directory(request.output_dir);
  const fs::path out(request.output_dir);
  io::write_file_atomic((out / "config.yaml").string(), slam::to_yaml(config));

  // Ground truth is read before the run so that a broken file is reported at once.
  std::optional<Trajectory> groundtruth;
  if (const auto gt_path = sequence.groundtruth_path()) {
    groundtruth = io::read_tum_trajectory(*gt_path);
    if (is_bonn(request.sequence_dir)) groundtruth = eval::bonn_marker_to_camera(*groundtruth);
  }

  std::size_t total = sequence.frames().size();
  if (request.max_frames > 0) total = std::min(total, static_cast<std::size_t>(request.max_frames));
  slam::System system(config.camera, config.options);
  ProgressBar bar(request.progress, total);

  // Stage names in first-seen order, and per-frame rows.
  std::vector<std::string> stage_names;
  std::map<std::string, std::vector<double>> stage_samples;
  std::vector<double> tracking_ms, load_ms;
  std::map<std::string, std::vector<double>> counts;  // per-frame feature and inlier counts
  std::ostringstream rows;
  int lost = 0, relocalised = 0, keyframes_inserted = 0, tracked = 0;
  std::vector<std::vector<std::pair<std::string, double>>> frame_stages;
  std::vector<std::string> frame_prefix;
  Stopwatch wall;
  for (std::size_t i = 0; i < total; ++i) {
    const io::FrameEntry& entry = sequence.frames()[i];
    Stopwatch load_watch;
    const io::RgbdImages images = io::load_rgbd(entry, config.camera.depth_factor);
    if (images.rgb.cols != config.camera.width || images.rgb.rows != config.camera.height)
      throw InputError(file_error(entry.rgb_path, "image is " + std::to_string(images.rgb.cols) +
                                                      "x" + std::to_string(images.rgb.rows) +
                                                      " but the camera is " +
                                                      std::to_string(config.camera.width) + "x" +
                                                      std::to_string(config.camera.height)));
    load_ms.push_back(load_watch.elapsed_ms());
    const slam::FrameResult r =
        system.process(images.rgb, images.depth, entry.rgb_timestamp, entry.depth_timestamp);
    tracked += r.state == slam::TrackingState::kOk ? 1 : 0;
    lost += r.state == slam::TrackingState::kLost ? 1 : 0;
    relocalised += r.relocalised ? 1 : 0;
    keyframes_inserted += r.keyframe ? 1 : 0;
    tracking_ms.push_back(r.times.total_ms());
    for (const auto& [name, ms] : r.times.stages) {
      if (stage_samples.find(name) == stage_samples.end()) stage_names.push_back(name);
      stage_samples[name].push_back(ms);
    }
    std::ostringstream prefix;
    prefix << r.frame_id << ',' << std::fixed << std::setprecision(6) << r.timestamp << ','
           << slam::to_string(r.state) << ',' << r.features << ',' << r.lines << ',' << r.planes
           << ',' << r.matches << ',' << r.inliers << ',' << r.line_matches << ',' << r.line_inliers
           << ',' << r.plane_inliers << ',' << (r.keyframe ? 1 : 0);
    counts["points"].push_back(r.features);
    counts["lines"].push_back(r.lines);
    counts["planes"].push_back(r.planes);
    if (r.state == slam::TrackingState::kOk) {
      counts["point_inliers"].push_back(r.inliers);
      counts["line_inliers"].push_back(r.line_inliers);
      counts["plane_inliers"].push_back(r.plane_inliers);
    }
    frame_prefix.push_back(prefix.str());
    frame_stages.push_back(r.times.stages);
    bar.update(i + 1, (i + 1) / (wall.elapsed_ms() / 1000.0), lost);
  }
  system.finish();
  const double wall_s = wall.elapsed_ms() / 1000.0;

  // Outputs.
  const Trajectory trajectory = system.trajectory();
  io::write_tum_trajectory((out / "trajectory.txt").string(), trajectory);
  io::write_tum_trajectory((out / "trajectory_online.txt").string(), system.online_trajectory());
  io::write_file_atomic((out / "keyframes.txt").string(),
                        format_tum_keyframes(system.keyframe_trajectory()));
  std::ostringstream csv;
  csv << "frame,timestamp,state,points,lines,planes,point_matches,point_inliers,line_matches,"
         "line_inliers,plane_inliers,keyframe";
  for (const auto& name : stage_names) csv << ',' << name << "_ms";
  csv << ",total_ms\n";
  for (std::size_t i = 0; i < frame_prefix.size(); ++i) {
    csv << frame_prefix[i];
    for (const auto& name : stage_names) {
      double ms = 0.0;
      for (const auto& s : frame_stages[i])
        if (s.first == name) ms += s.second;
      csv << ',' << std::fixed << std::setprecision(3) << ms;
    }
    csv << ',' << std::fixed << std::setprecision(3) << tracking_ms[i] << '\n';
  }
  io::write_file_atomic((out / "timings.csv").string(), csv.str());

  nlohmann::json summary;
  summary["sequence"] = fs::path(request.sequence_dir).lexically_normal().string();
  summary["camera_source"] = config.camera_source;
  summary["sequential"] = config.options.sequential;
  summary["frames"] = total;
  summary["tracked_frames"] = tracked;
  summary["tracked_ratio"] = total == 0 ? 0.0 : static_cast<double>(tracked) / total;
  summary["lost_frames"] = lost;
  summary["not_initialized_frames"] = static_cast<int>(total) - tracked - lost;
  summary["relocalisations"] = relocalised;
  summary["keyframes_inserted"] = keyframes_inserted;
  {
    auto lock = system.map().read_lock();
    summary["keyframes_in_map"] = system.map().num_keyframes();
    summary["points_in_map"] = system.map().num_points();
    summary["lines_in_map"] = system.map().num_lines();
    summary["planes_in_map"] = system.map().num_planes();
    if (request.save_map) {
      io::write_file_atomic((out / "map.ply").string(), map::map_to_ply(system.map()));
      io::write_file_atomic((out / "map.json").string(),
                            map::map_to_json(system.map()).dump(1) + "\n");
    }
  }
  summary["features"] = {{"points", config.options.use.points},
                         {"lines", config.options.use.lines},
                         {"planes", config.options.use.planes}};
  nlohmann::json per_frame = nlohmann::json::object();
  for (const auto& [name, samples] : counts) {
    const SampleStats st = compute_stats(samples);
    per_frame[name] = {{"median", st.median}, {"mean", st.mean}, {"max", st.max}};
  }
  summary["per_frame_counts"] = per_frame;
  summary["wall_time_s"] = wall_s;
  summary["frames_per_second"] = wall_s > 0 ? total / wall_s : 0.0;
  summary["peak_rss_mib"] = peak_rss_mib();
  nlohmann::json stages = nlohmann::json::object();
  for (const auto& name : stage_names) {
    // Stages that did not run on a frame count as 0 there only for the per-frame total.
    const SampleStats s = compute_stats(stage_samples[name]);
    stages[name] = {
        {"median_ms", s.median}, {"p95_ms", s.p95}, {"mean_ms", s.mean}, {"frames", s.count}};
  }
  const SampleStats track_stats = compute_stats(tracking_ms);
  stages["tracking_total"] = {{"median_ms", track_stats.median},
                              {"p95_ms", track_stats.p95},
                              {"mean_ms", track_stats.mean},
                              {"frames", track_stats.count}};
  const SampleStats load_stats = compute_stats(load_ms);
  stages["image_load"] = {{"median_ms", load_stats.median},
                          {"p95_ms", load_stats.p95},
                          {"mean_ms", load_stats.mean},
                          {"frames", load_stats.count}};
  if (!config.options.sequential) {
    std::map<std::string, std::vector<double>> mapper_samples;
    for (const auto& t : system.mapper_times())
      for (const auto& [name, ms] : t.stages) mapper_samples[name].push_back(ms);
    nlohmann::json mapper = nlohmann::json::object();
    for (const auto& [name, samples] : mapper_samples) {
      const SampleStats s = compute_stats(samples);
      mapper[name] = {{"median_ms", s.median}, {"p95_ms", s.p95}, {"keyframes", s.count}};
    }
    summary["mapper_stages"] = mapper;
  }
  summary["stages"] = stages;
  summary["warnings"] = sequence.warnings();
  if (groundtruth && !trajectory.empty()) {
    try {
      const eval::EvalReport report = eval::evaluate(*groundtruth, trajectory);
      summary["eval"] = eval::to_json(report);
      summary["ate_rmse_m"] = report.ate.translation.rmse;
    } catch (const InputError& e) {
      summary["eval_error"] = e.what();
    }
  }
  io::write_file_atomic((out / "summary.json").string(), summary.dump(2) + "\n");
  return summary;
}

std::string summary_text(const nlohmann::json& s) {
  std::ostringstream o;
  o << std::fixed;
  o << "frames " << s["frames"].get<int>() << ", tracked " << std::setprecision(1)
    << 100.0 * s["tracked_ratio"].get<double>() << "%, lost " << s["lost_frames"].get<int>()
    << ", relocalised " << s["relocalisations"].get<int>() << ", keyframes "
    << s["keyframes_in_map"].get<int>() << "\n";
  o << "map: " << s["points_in_map"].get<int>() << " points, " << s["lines_in_map"].get<int>()
    << " lines, " << s["planes_in_map"].get<int>() << " planes\n";
  o << "speed " << std::setprecision(1) << s["frames_per_second"].get<double>()
    << " fps; tracking median " << std::setprecision(1)
    << s["stages"]["tracking_total"]["median_ms"].get<double>() << " ms, p95 "
    << s["stages"]["tracking_total"]["p95_ms"].get<double>() << " ms; peak memory "
    << std::setprecision(0) << s["peak_rss_mib"].get<double>() << " MiB\n";
  if (s.contains("ate_rmse_m"))
    o << "ATE RMSE " << std::setprecision(4) << s["ate_rmse_m"].get<double>() << " m over "
      << s["eval"]["matched"].get<int>() << " poses\n";
  else if (s.contains("eval_error"))
    o << "no ATE: " << s["eval_error"].get<std::string>() << "\n";
  return o.str();
}

}  // namespace mcslam::app
