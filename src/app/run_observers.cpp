#include "run_observers.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "mcslam/app/run.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/io/trajectory_io.hpp"

namespace mcslam::app {
namespace {

int count_labels(const std::vector<slam::FeatureLabel>& labels, slam::FeatureLabel label) {
  return static_cast<int>(std::count(labels.begin(), labels.end(), label));
}

}  // namespace

double current_rss_mib() {
  std::ifstream statm("/proc/self/statm");
  long long pages = 0, resident = 0;
  if (!(statm >> pages >> resident)) return 0.0;
  return static_cast<double>(resident) * static_cast<double>(::sysconf(_SC_PAGESIZE)) /
         (1024.0 * 1024.0);
}

RunStatus::RunStatus(std::string path, std::size_t frames_total)
    : path_(std::move(path)), frames_total_(frames_total) {
  write("running", 0, {});
}

void RunStatus::failed(const std::string& error) {
  try {
    write("failed", frames_done_, error);
  } catch (const InputError&) {
  }
}

void RunStatus::write(const std::string& state, std::size_t frames_done, const std::string& error) {
  frames_done_ = frames_done;
  nlohmann::json j = {{"state", state},
                      {"frames_done", frames_done},
                      {"frames_total", frames_total_},
                      {"pid", static_cast<long long>(::getpid())}};
  if (!error.empty()) j["error"] = error;
  io::write_file_atomic(path_, j.dump(2) + "\n");
}

void StageTable::add_frame(const StageTimes& times) {
  std::vector<float> row(names.size(), 0.0f);
  for (const auto& [name, ms] : times.stages) {
    auto it = index.find(name);
    if (it == index.end()) {
      it = index.emplace(name, names.size()).first;
      names.push_back(name);
      row.push_back(0.0f);
    }
    row[it->second] += static_cast<float>(ms);  // a stage may run twice on a frame
  }
  rows.push_back(std::move(row));
}

void FrameRecorder::on_frame(const FrameEvent& e) {
  const slam::FrameResult& r = e.result;
  load_ms.push_back(e.wait_ms);
  dropped_before.push_back(e.dropped_before);
  if (e.latency_ms) latency_ms.push_back(*e.latency_ms);
  if (r.lagged) {
    lagged_delay_ms.push_back(1000.0 * (r.timestamp - r.lagged->timestamp));
    if (e.latency_ms) lagged_latency_ms.push_back(lagged_delay_ms.back() + *e.latency_ms);
  }
  tracked += r.state == slam::TrackingState::kOk ? 1 : 0;
  if (r.state == slam::TrackingState::kOk) ++online_poses[r.online_pose];
  lost += r.state == slam::TrackingState::kLost ? 1 : 0;
  relocalised += r.relocalised ? 1 : 0;
  if (r.relocalisation) {
    ++reloc_attempts;
    const bool from_last_pose = r.relocalisation->from_last_pose;
    if (!from_last_pose) reloc_query_ms.push_back(r.relocalisation->query_ms);
    reloc_by_database = reloc_by_database || r.relocalisation->by_database;
    recovered += r.relocalised && from_last_pose ? 1 : 0;
    if (r.relocalised)
      reloc_events.push_back({{"frame", r.frame_id},
                              {"timestamp", r.timestamp},
                              {"from_last_pose", from_last_pose},
                              {"by_database", r.relocalisation->by_database},
                              {"keyframe", r.relocalisation->keyframe},
                              {"score", r.relocalisation->score},
                              {"candidates", r.relocalisation->candidates},
                              {"query_ms", r.relocalisation->query_ms},
                              {"match_ms", r.relocalisation->match_ms}});
  }
  keyframes_inserted += r.keyframe ? 1 : 0;
  tracking_ms.push_back(r.times.total_ms());
  rss_mib.push_back(static_cast<float>(current_rss_mib()));
  stage_table.add_frame(r.times);
  for (const auto& [name, ms] : r.times.stages) stage_samples[name].push_back(ms);
  std::ostringstream prefix;
  prefix << r.frame_id << ',' << std::fixed << std::setprecision(6) << r.timestamp << ','
         << slam::to_string(r.state) << ',' << r.features << ',' << r.lines << ',' << r.planes
         << ',' << r.matches << ',' << r.inliers << ',' << r.line_matches << ',' << r.line_inliers
         << ',' << r.plane_inliers << ',' << (r.keyframe ? 1 : 0);
  const int dynamic_points = count_labels(r.point_labels, slam::FeatureLabel::kDynamic);
  const int constrained_points = count_labels(r.point_labels, slam::FeatureLabel::kConstrained);
  int dynamic_objects = 0, constrained_objects = 0;
  for (const auto& o : r.objects) {
    dynamic_objects += o.state == slam::ObjectState::kDynamic ? 1 : 0;
    constrained_objects += o.state == slam::ObjectState::kConstrained ? 1 : 0;
  }
  prefix << ',' << r.objects.size() << ',' << dynamic_objects << ',' << constrained_objects << ','
         << dynamic_points << ',' << constrained_points << ',' << r.constrained_point_residuals
         << ',' << r.constrained_line_residuals;
  if (r.detections_used) {
    counts["dynamic_points"].push_back(dynamic_points);
    counts["constrained_points"].push_back(constrained_points);
  }
  counts["points"].push_back(r.features);
  counts["lines"].push_back(r.lines);
  counts["planes"].push_back(r.planes);
  if (r.state == slam::TrackingState::kOk) {
    counts["point_inliers"].push_back(r.inliers);
    counts["line_inliers"].push_back(r.line_inliers);
    counts["plane_inliers"].push_back(r.plane_inliers);
  }
  frame_prefix_.push_back(prefix.str());
}

std::string FrameRecorder::timings_csv(bool realtime) const {
  std::ostringstream csv;
  csv << "frame,timestamp,state,points,lines,planes,point_matches,point_inliers,line_matches,"
         "line_inliers,plane_inliers,keyframe,objects,dynamic_objects,constrained_objects,"
         "dynamic_points,constrained_points,constrained_point_residuals,"
         "constrained_line_residuals";
  for (const auto& name : stage_table.names) csv << ',' << name << "_ms";
  csv << ",total_ms,rss_mib";
  // In real time: the frames dropped just before each processed one, and its latency (from the
  // frame's time to its pose).
  if (realtime) csv << ",dropped_before,latency_ms";
  csv << '\n';
  for (std::size_t i = 0; i < frame_prefix_.size(); ++i) {
    csv << frame_prefix_[i] << std::fixed << std::setprecision(3);
    for (std::size_t k = 0; k < stage_table.names.size(); ++k) csv << ',' << stage_table.at(i, k);
    csv << ',' << tracking_ms[i] << ',' << std::setprecision(1) << rss_mib[i];
    if (realtime) csv << ',' << dropped_before[i] << ',' << latency_ms[i];
    csv << '\n';
  }
  return csv.str();
}

nlohmann::json objects_json(const slam::FrameResult& r) {
  nlohmann::json objects = nlohmann::json::array();
  for (const slam::ObjectReport& o : r.objects) {
    const auto& b = o.detection.box;
    nlohmann::json j = {{"track", o.track_id},
                        {"class", o.detection.class_name},
                        {"class_id", o.detection.class_id},
                        {"score", o.detection.score},
                        {"box", {b.x, b.y, b.width, b.height}},
                        {"state", slam::to_string(o.state)},
                        {"matches", o.decision.matches},
                        {"own_f", o.decision.own_f},
                        {"ransac_inliers", o.decision.ransac_inliers},
                        {"counted", o.decision.counted},
                        {"outliers", o.decision.outliers},
                        {"outlier_ratio", o.decision.outlier_ratio},
                        {"median_distance_px", o.decision.median_distance},
                        {"decided", o.decision.decided},
                        {"source", slam::to_string(o.source)},
                        {"propagated_matches", o.propagated_matches},
                        {"background_points", o.background_points}};
    if (o.depth_far > 0.0f) j["depth_band_m"] = {o.depth_near, o.depth_far};
    if (o.world_box) {
      const Eigen::Vector3d& lo = o.world_box->first;
      const Eigen::Vector3d& hi = o.world_box->second;
      j["world_box_m"] = {{"min", {lo.x(), lo.y(), lo.z()}}, {"max", {hi.x(), hi.y(), hi.z()}}};
    }
    if (o.velocity) j["velocity_mps"] = {o.velocity->x(), o.velocity->y(), o.velocity->z()};
    if (o.constraint.plane >= 0 || o.constraint.points > 0)
      j["constraint"] = {{"constrained", o.constraint.constrained},
                         {"plane", o.constraint.plane},
                         {"distance_change_m", o.constraint.distance_change},
                         {"angle_change_deg", o.constraint.angle_change_deg},
                         {"points", o.constraint.points},
                         {"lines", o.constraint.lines}};
    objects.push_back(j);
  }
  return objects;
}

ObjectsRecorder::ObjectsRecorder(std::optional<std::string> path) {
  if (!path) return;
  file_.emplace(*path);
  file_->append("{\"frames\": [\n");
}

void ObjectsRecorder::on_frame(const FrameEvent& e) {
  const slam::FrameResult& r = e.result;
  for (const auto& o : r.objects) ++object_states[slam::to_string(o.state)];
  if (!r.detections_used) return;
  detection_age.push_back(r.detections_age);
  if (r.detect_ms) detect_ms.push_back(*r.detect_ms);
  if (r.propagation_iou >= 0.0) {
    propagation_iou.push_back(r.propagation_iou);
    stale_iou.push_back(r.stale_iou);
  }
  mover_frames += r.mover_regions > 0 ? 1 : 0;
  fresh_frames += r.detections_fresh ? 1 : 0;
  if (file_) {
    const nlohmann::json frame_objects = {
        {"frame", r.frame_id},
        {"timestamp", r.timestamp},
        {"fresh", r.detections_fresh},
        {"epsilon_d_px", r.dynamics_threshold},
        {"age", r.detections_age},
        {"dynamic_points", count_labels(r.point_labels, slam::FeatureLabel::kDynamic)},
        {"constrained_points", count_labels(r.point_labels, slam::FeatureLabel::kConstrained)},
        {"dynamic_lines", count_labels(r.line_labels, slam::FeatureLabel::kDynamic)},
        {"constrained_lines", count_labels(r.line_labels, slam::FeatureLabel::kConstrained)},
        {"constrained_residuals", {r.constrained_point_residuals, r.constrained_line_residuals}},
        {"mover_regions", r.mover_regions},
        {"mover_points", r.mover_points},
        {"objects", objects_json(r)}};
    file_->append((frames_with_boxes > 0 ? ",\n" : "") + frame_objects.dump(1));
  }
  ++frames_with_boxes;
}

void ObjectsRecorder::commit() {
  if (!file_ || frames_with_boxes == 0) return;
  file_->append("\n]}\n");
  file_->commit();
}

void OverlayWriter::on_frame(const FrameEvent& e) {
  cv::Mat overlay = e.system.undistort(e.images.rgb);
  if (overlay.channels() != 3) return;
  overlay = overlay.clone();
  draw_overlay(overlay, e.result);
  char name[32];
  std::snprintf(name, sizeof(name), "%06llu.jpg",
                static_cast<unsigned long long>(e.result.frame_id));
  const std::string path = (folder_ / name).string();
  if (!cv::imwrite(path, overlay)) throw InputError(file_error(path, "cannot write"));
}

void PassRecorder::on_frame(const FrameEvent& e) {
  done_ = e.done;
  if (done_ % frames_per_pass_ == 0 || done_ == total_) record(e.system, done_);
}

void PassRecorder::on_stream_end(slam::System& system) {
  if (done_ > passes_.size() * frames_per_pass_) record(system, done_);  // stopped in a pass
}

void PassRecorder::record(slam::System& system, std::size_t done) {
  PassFigures p;
  const std::size_t begin = passes_.size() * frames_per_pass_;
  for (std::size_t f = begin; f < done; ++f) p.tracking_ms.push_back(frames_.tracking_ms[f]);
  p.frames = static_cast<int>(done - begin);
  p.wall_s = watch_.elapsed_ms() / 1000.0;
  watch_.restart();
  p.rss_end_mib = current_rss_mib();
  {
    auto lock = system.map().read_lock();
    p.keyframes_in_map = system.map().num_keyframes();
    p.points_in_map = system.map().num_points();
    p.lines_in_map = system.map().num_lines();
  }
  // Counters so far minus those of the passes before.
  p.tracked = frames_.tracked;
  p.lost = frames_.lost;
  p.relocalised = frames_.relocalised;
  p.keyframes_inserted = frames_.keyframes_inserted;
  for (const PassFigures& q : passes_) {
    p.tracked -= q.tracked;
    p.lost -= q.lost;
    p.relocalised -= q.relocalised;
    p.keyframes_inserted -= q.keyframes_inserted;
  }
  passes_.push_back(std::move(p));
}

void Checkpointer::on_frame(const FrameEvent& e) {
  if (watch_.elapsed_ms() <= 2000.0 || (!live_ && e.offered >= total_)) return;
  io::write_tum_trajectory((out_ / "trajectory_online.txt").string(), e.system.online_trajectory(),
                           "partial: the run was at frame " + std::to_string(e.offered) + " of " +
                               std::to_string(total_) + " (see status.json)");
  status_.running(e.offered);
  watch_.restart();
}

void ProgressObserver::on_frame(const FrameEvent& e) {
  const std::size_t done = e.offered;
  if (done % 5 != 0 && done != total_) return;
  const double fps = e.done / (wall_.elapsed_ms() / 1000.0);
  const int width = 30;
  const int filled = total_ == 0 ? width : static_cast<int>(width * done / total_);
  std::fprintf(stderr, "\r[%s%s] %zu/%zu  %.1f fps  lost %d ", std::string(filled, '#').c_str(),
               std::string(width - filled, '.').c_str(), done, total_, fps, frames_.lost);
  if (done == total_) std::fputc('\n', stderr);
  std::fflush(stderr);
}

}  // namespace mcslam::app
