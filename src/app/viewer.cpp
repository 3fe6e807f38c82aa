#include "mcslam/app/viewer.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "mcslam/app/run.hpp"
#include "mcslam/core/data_files.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/core/worker.hpp"
#include "mcslam/mapping/worker.hpp"

namespace mcslam::app {
namespace {

constexpr std::size_t kRecent = 120;  // tracking times in the rolling plot

/// Passes per second between the oldest and the newest sample.
double detector_rate_hz(const std::vector<std::pair<double, std::size_t>>& samples) {
  if (samples.size() < 2) return 0.0;
  const double dt = samples.back().first - samples.front().first;
  return dt > 0.0 ? static_cast<double>(samples.back().second - samples.front().second) / dt : 0.0;
}

/// The binary messages: one byte of type, three of padding, then the body.
enum : std::uint8_t { kFrameMessage = 1, kMapMessage = 2, kOccupancyMessage = 3 };

const char* kPage = R"(<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>mcslam live</title>
<link rel="icon" href="data:,">
</head>
<body>
<noscript>The live viewer needs JavaScript.</noscript>
<script src="/viewer.js"></script>
</body>
</html>
)";

std::string read_page_script() {
  const std::string path = find_data_file("viewer/viewer.js");
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw InputError("--viewer: the page's scripts are missing (" + path +
                     "): build them with the npm packages of web/report (scripts/install-deps.sh, "
                     "then rebuild), or set MCSLAM_DATA_DIR");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void append_bytes(std::string& out, const void* data, std::size_t n) {
  out.append(static_cast<const char*>(data), n);
}

void pad4(std::string& out) {
  while (out.size() % 4 != 0) out.push_back('\0');
}

template <typename T>
void append_vector(std::string& out, const std::vector<T>& v) {
  append_bytes(out, v.data(), v.size() * sizeof(T));
  pad4(out);
}

/// Every `stride`-th element group of `values` (groups of `group` values).
std::vector<float> thin(const std::vector<float>& values, std::size_t group, std::size_t max) {
  const std::size_t n = values.size() / group;
  if (n <= max || max == 0) return values;
  std::vector<float> out;
  out.reserve(max * group);
  for (std::size_t k = 0; k < max; ++k) {
    const std::size_t i = k * n / max;
    out.insert(out.end(), values.begin() + i * group, values.begin() + (i + 1) * group);
  }
  // The newest always stays (the trajectory's end is where the camera is).
  out.insert(out.end(), values.end() - group, values.end());
  return out;
}

/// The type byte, padding, the header's length and the header, padded to 4 bytes.
std::string message_start(std::uint8_t type, const nlohmann::json& header) {
  const std::string text = header.dump();
  std::string out;
  const std::uint8_t start[4] = {type, 0, 0, 0};
  append_bytes(out, start, 4);
  const std::uint32_t length = static_cast<std::uint32_t>(text.size());
  append_bytes(out, &length, 4);
  out += text;
  pad4(out);
  return out;
}

}  // namespace

std::string occupancy_message(const mapping::OccupancySnapshot& snapshot, std::size_t max_voxels) {
  const mapping::OccupancyGrid& grid = snapshot.grid;
  const std::size_t all = snapshot.voxels.size();
  const std::size_t n = max_voxels == 0 ? all : std::min(all, max_voxels);
  std::vector<float> centres, sizes;
  std::vector<std::uint8_t> colours;
  centres.reserve(3 * n);
  sizes.reserve(n);
  colours.reserve(3 * n);
  for (std::size_t k = 0; k < n; ++k) {
    const mapping::OccupiedVoxel& v = snapshot.voxels[k * all / n];  // evenly, when thinned
    centres.insert(centres.end(),
                   {static_cast<float>(v.centre.x()), static_cast<float>(v.centre.y()),
                    static_cast<float>(v.centre.z())});
    sizes.push_back(static_cast<float>(v.size));
    colours.insert(colours.end(), v.rgb.begin(), v.rgb.end());
  }
  const nlohmann::json header = {{"version", snapshot.version},
                                 {"width", grid.width},
                                 {"height", grid.height},
                                 {"resolution", grid.resolution},
                                 {"voxels", n},
                                 {"voxels_in_map", all},
                                 {"floor_estimated", grid.floor_estimated}};
  std::string out = message_start(kOccupancyMessage, header);
  out.reserve(out.size() + 64 + grid.cells.size() + 3 + 19 * n);
  const Eigen::Matrix4f T = grid.T_world_grid.cast<float>();  // column-major, as three.js takes it
  append_bytes(out, T.data(), 16 * sizeof(float));
  append_vector(out, grid.cells);
  append_vector(out, centres);
  append_vector(out, sizes);
  append_vector(out, colours);
  return out;
}

std::optional<std::string> ViewerOptions::check() const {
  if (auto e = server.check()) return e;
  if (!(frame_hz > 0.0 && frame_hz <= 30.0)) return "frame_hz: must be in (0, 30]";
  if (!(stats_hz > 0.0 && stats_hz <= 30.0)) return "stats_hz: must be in (0, 30]";
  if (!(map_hz > 0.0 && map_hz <= 10.0)) return "map_hz: must be in (0, 10]";
  if (jpeg_quality < 10 || jpeg_quality > 100) return "jpeg_quality: must be 10..100";
  if (max_map_points < 1000) return "max_map_points: must be at least 1000";
  if (max_trajectory_points < 100) return "max_trajectory_points: must be at least 100";
  if (max_voxels < 1000) return "max_voxels: must be at least 1000";
  return std::nullopt;
}

Viewer::Viewer(const ViewerOptions& options, RunControl& control, std::string sequence,
               std::size_t total, const std::optional<Trajectory>& groundtruth)
    : options_(options), control_(control), total_(total) {
  if (auto e = options.check()) throw InputError("viewer: " + *e);
  std::map<std::string, ServedFile> files;
  files["/"] = {"text/html; charset=utf-8", kPage};
  files["/index.html"] = files["/"];
  files["/viewer.js"] = {"text/javascript; charset=utf-8", read_page_script()};
  server_ = std::make_unique<ViewerServer>(options.server, std::move(files),
                                           [this](const std::string& text) { on_message(text); });
  sequence_ = std::move(sequence);
  if (groundtruth) groundtruth_ = *groundtruth;
  server_->publish(ViewerChannel::kHello, hello_json(), false);
  thread_ = std::thread([this] {
    set_current_thread_name("mcslam-view");
    loop_guarded();
  });
}

Viewer::~Viewer() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  server_.reset();
}

std::string Viewer::hello_json() const {
  // What a client needs once: the run and the ground truth (thinned).
  nlohmann::json hello = {{"type", "hello"},
                          {"sequence", sequence_},
                          {"total", total_},
                          {"frame_hz", options_.frame_hz},
                          {"map_hz", options_.map_hz}};
  SE3 T_map_gt;  // identity until the first tracked pose
  bool aligned = false;
  if (anchor_ && !groundtruth_.empty()) {
    const auto nearest = std::min_element(groundtruth_.begin(), groundtruth_.end(),
                                          [&](const StampedPose& a, const StampedPose& b) {
                                            return std::abs(a.timestamp - anchor_->timestamp) <
                                                   std::abs(b.timestamp - anchor_->timestamp);
                                          });
    if (std::abs(nearest->timestamp - anchor_->timestamp) < 0.1) {
      T_map_gt = anchor_->T_w_c * nearest->T_w_c.inverse();
      aligned = true;
    }
  }
  std::vector<float> gt;
  gt.reserve(3 * groundtruth_.size());
  for (const StampedPose& p : groundtruth_) {
    const Eigen::Vector3d t = T_map_gt * p.T_w_c.translation();
    gt.insert(gt.end(),
              {static_cast<float>(t.x()), static_cast<float>(t.y()), static_cast<float>(t.z())});
  }
  hello["groundtruth"] = thin(gt, 3, options_.max_trajectory_points);
  hello["groundtruth_aligned"] = aligned;
  return hello.dump();
}

std::string Viewer::url() const {
  return "http://" + options_.server.bind + ":" + std::to_string(port()) + "/";
}

void Viewer::on_frame(const FrameEvent& e) {
  const slam::FrameResult& r = e.result;
  const double now = wall_.elapsed_ms() / 1000.0;
  if (!system_known_) {
    std::lock_guard<std::mutex> lock(system_mutex_);
    system_ = &e.system;
    system_known_ = true;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  done_ = e.done;
  frame_id_ = r.frame_id;
  timestamp_ = r.timestamp;
  state_ = slam::to_string(r.state);
  tracking_ms_.push_back(r.times.total_ms());
  frame_s_.push_back(now);
  if (frame_s_.size() > 30) frame_s_.erase(frame_s_.begin());
  if (tracking_ms_.size() > kRecent) tracking_ms_.erase(tracking_ms_.begin());
  // The detector's passes, whichever frame used their boxes (a threaded run uses boxes a few
  // frames old: counting the frames with boxes of their own would show no pass at all).
  if (const slam::DetectionSource* source = e.system.detection_source()) {
    detector_passes_.emplace_back(now, source->pass_count());
    while (detector_passes_.size() > 2 && detector_passes_.front().first < now - 3.0)
      detector_passes_.erase(detector_passes_.begin());
  }
  box_age_ = r.detections_used ? r.detections_age : -1;
  objects_ = static_cast<int>(r.objects.size());
  dynamic_objects_ = constrained_objects_ = 0;
  object_boxes_.clear();
  for (const auto& o : r.objects) {
    const bool dynamic = o.state == slam::ObjectState::kDynamic;
    const bool constrained = o.state == slam::ObjectState::kConstrained;
    dynamic_objects_ += dynamic ? 1 : 0;
    constrained_objects_ += constrained ? 1 : 0;
    if ((dynamic || constrained) && o.world_box)
      object_boxes_.push_back({o.world_box->first, o.world_box->second, constrained,
                               o.detection.class_name, o.track_id});
  }
  keyframes_ += r.keyframe ? 1 : 0;
  pose_ = r.T_w_c;
  if (r.T_w_c && !anchor_) anchor_ = StampedPose{r.timestamp, *r.T_w_c};
  if (r.T_w_c) {
    const Eigen::Vector3d t = r.T_w_c->translation();
    trajectory_.insert(trajectory_.end(), {static_cast<float>(t.x()), static_cast<float>(t.y()),
                                           static_cast<float>(t.z())});
  }
  // The frame itself at most frame_hz times a second: a copy of the result (its features are
  // shared) and a reference to the colour image; the thread draws and encodes.
  if (last_handoff_s_ < 0.0 || now - last_handoff_s_ >= 1.0 / options_.frame_hz) {
    pending_ = PendingFrame{r, e.images.rgb};
    last_handoff_s_ = now;
    wake_.notify_one();
  }
}

void Viewer::on_stream_end(slam::System& system) {
  std::string map;
  {
    std::lock_guard<std::mutex> lock(system_mutex_);
    map = map_message(system);
    send_occupancy(system);
  }
  detach();
  server_->publish(ViewerChannel::kMap, std::move(map), true);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    finished_ = true;
    urgent_stats_ = true;
  }
  wake_.notify_all();
}

void Viewer::detach() {
  std::lock_guard<std::mutex> lock(system_mutex_);
  system_ = nullptr;
}

void Viewer::on_message(const std::string& text) {
  // {"cmd": "pause" | "resume" | "localize" | "map"}; anything else is ignored.
  const nlohmann::json message = nlohmann::json::parse(text, nullptr, false);
  if (!message.is_object() || !message.contains("cmd") || !message["cmd"].is_string()) return;
  const std::string cmd = message["cmd"].get<std::string>();
  if (cmd == "pause")
    control_.pause();
  else if (cmd == "resume")
    control_.resume();
  else if (cmd == "localize")
    control_.request_localize(true);
  else if (cmd == "map")
    control_.request_localize(false);
  else
    return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    urgent_stats_ = true;
  }
  wake_.notify_all();
}

std::string Viewer::stats_json() {
  nlohmann::json j = {{"type", "stats"},
                      {"frame", frame_id_},
                      {"timestamp", timestamp_},
                      {"done", done_},
                      {"total", total_},
                      {"state", state_},
                      {"fps", frame_s_.size() > 1 && frame_s_.back() > frame_s_.front()
                                  ? (frame_s_.size() - 1) / (frame_s_.back() - frame_s_.front())
                                  : 0.0},
                      {"tracking_ms", tracking_ms_.empty() ? 0.0 : tracking_ms_.back()},
                      {"tracking_recent", tracking_ms_},
                      {"detector_hz", detector_rate_hz(detector_passes_)},
                      {"box_age", box_age_},
                      {"objects", objects_},
                      {"dynamic_objects", dynamic_objects_},
                      {"constrained_objects", constrained_objects_},
                      {"keyframes_inserted", keyframes_},
                      {"map_points", map_points_},
                      {"paused", control_.paused()},
                      {"held", control_.held()},
                      {"localize", control_.localize_requested()},
                      {"finished", finished_},
                      {"frames_sent", frames_sent_.load()},
                      {"maps_sent", maps_sent_.load()},
                      {"occupancy_sent", occupancy_sent_.load()},
                      {"clients", server_->stats().clients}};
  nlohmann::json boxes = nlohmann::json::array();
  for (const ObjectBox& b : object_boxes_)
    boxes.push_back({{"min", std::array<double, 3>{b.min.x(), b.min.y(), b.min.z()}},
                     {"max", std::array<double, 3>{b.max.x(), b.max.y(), b.max.z()}},
                     {"state", b.constrained ? "constrained" : "dynamic"},
                     {"class", b.class_name},
                     {"track", b.track_id}});
  j["object_boxes"] = std::move(boxes);
  if (pose_) {
    const Eigen::Matrix4d T = pose_->matrix();
    std::vector<double> m(T.data(), T.data() + 16);  // column-major, as three.js takes it
    j["pose"] = m;
  } else {
    j["pose"] = nullptr;
  }
  return j.dump();
}

std::string Viewer::map_message(slam::System& system) {
  std::vector<float> points, lines, keyframes, hulls;
  std::vector<std::uint8_t> colors;
  nlohmann::json planes = nlohmann::json::array();
  std::size_t loops = 0;
  {
    const map::Map& map = system.map();
    auto lock = map.read_lock();
    points.reserve(3 * map.points().size());
    colors.reserve(3 * map.points().size());
    for (const auto& [id, p] : map.points()) {
      points.insert(points.end(), {static_cast<float>(p.p_w.x()), static_cast<float>(p.p_w.y()),
                                   static_cast<float>(p.p_w.z())});
      colors.insert(colors.end(), p.color.begin(), p.color.end());
    }
    for (const auto& [id, l] : map.lines())
      lines.insert(lines.end(),
                   {static_cast<float>(l.start_w.x()), static_cast<float>(l.start_w.y()),
                    static_cast<float>(l.start_w.z()), static_cast<float>(l.end_w.x()),
                    static_cast<float>(l.end_w.y()), static_cast<float>(l.end_w.z())});
    for (const auto& [id, kf] : map.keyframes()) {
      const Eigen::Vector3d c = kf.camera_center();
      keyframes.insert(keyframes.end(), {static_cast<float>(c.x()), static_cast<float>(c.y()),
                                         static_cast<float>(c.z())});
    }
    for (const auto& [id, plane] : map.planes()) {
      if (plane.hull.size() < 3) continue;
      planes.push_back({{"id", id}, {"corners", plane.hull.size()}});
      for (const auto& c : plane.hull)
        hulls.insert(hulls.end(), {static_cast<float>(c.x()), static_cast<float>(c.y()),
                                   static_cast<float>(c.z())});
    }
  }
  for (const auto& e : system.loop_statistics().events) loops += e.accepted ? 1 : 0;
  const std::size_t all_points = points.size() / 3;
  if (all_points > options_.max_map_points) {
    std::vector<std::uint8_t> thinned_colors;
    const std::size_t n = all_points, max = options_.max_map_points;
    for (std::size_t k = 0; k < max; ++k) {
      const std::size_t i = k * n / max;
      thinned_colors.insert(thinned_colors.end(), colors.begin() + 3 * i,
                            colors.begin() + 3 * i + 3);
    }
    points = thin(points, 3, max);
    points.resize(3 * max);  // thin() keeps the last one too: not here
    colors = std::move(thinned_colors);
  }
  std::vector<float> trajectory;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    trajectory = thin(trajectory_, 3, options_.max_trajectory_points);
    map_points_ = all_points;
  }
  const nlohmann::json header = {{"points", points.size() / 3},
                                 {"points_in_map", all_points},
                                 {"lines", lines.size() / 6},
                                 {"keyframes", keyframes.size() / 3},
                                 {"trajectory", trajectory.size() / 3},
                                 {"planes", planes},
                                 {"loops_closed", loops}};
  std::string out = message_start(kMapMessage, header);
  out.reserve(out.size() + 16 + 4 * (points.size() + lines.size() + trajectory.size()) +
              colors.size());
  append_vector(out, points);
  append_vector(out, colors);
  append_vector(out, lines);
  append_vector(out, keyframes);
  append_vector(out, trajectory);
  append_vector(out, hulls);
  return out;
}

void Viewer::send_frame(const PendingFrame& frame, const slam::System& system) {
  cv::Mat image = system.undistort(frame.rgb);
  if (image.channels() != 3) return;
  image = image.clone();
  draw_overlay(image, frame.result);
  std::vector<std::uint8_t> jpeg;
  if (!cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, options_.jpeg_quality})) return;
  std::string out;
  out.reserve(8 + jpeg.size());
  const std::uint8_t type[4] = {kFrameMessage, 0, 0, 0};
  append_bytes(out, type, 4);
  const std::uint32_t id = static_cast<std::uint32_t>(frame.result.frame_id);
  append_bytes(out, &id, 4);
  append_bytes(out, jpeg.data(), jpeg.size());
  server_->publish(ViewerChannel::kFrame, std::move(out), true);
}

void Viewer::send_occupancy(const slam::System& system) {
  const mapping::MappingWorker* worker = system.occupancy();
  if (!worker) return;
  // Cheap when the map has not changed since the last snapshot; built here otherwise.
  const std::shared_ptr<const mapping::OccupancySnapshot> snapshot = worker->snapshot();
  if (snapshot->version == occupancy_version_) return;
  occupancy_version_ = snapshot->version;
  server_->publish(ViewerChannel::kOccupancy, occupancy_message(*snapshot, options_.max_voxels),
                   true);
  ++occupancy_sent_;
}

void Viewer::loop_guarded() {
  try {
    loop();
  } catch (...) {
    failure_.set(std::current_exception());
  }
}

std::string Viewer::failure() const {
  if (failure_.failed()) return failure_.message();
  return server_->failure();
}

void Viewer::loop() {
  using namespace std::chrono;
  double last_stats = -1.0, last_map = -1.0;
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stop_) {
    wake_.wait_for(lock, milliseconds(40), [this] { return stop_ || pending_ || urgent_stats_; });
    if (stop_) break;
    std::optional<PendingFrame> frame = std::move(pending_);
    pending_.reset();
    const double now = wall_.elapsed_ms() / 1000.0;
    std::string stats;
    if (urgent_stats_ || last_stats < 0.0 || now - last_stats >= 1.0 / options_.stats_hz) {
      stats = stats_json();
      last_stats = now;
      urgent_stats_ = false;
    }
    const bool map_due = last_map < 0.0 || now - last_map >= 1.0 / options_.map_hz;
    std::string hello;
    if (!hello_aligned_ && anchor_) {
      hello = groundtruth_.empty() ? std::string() : hello_json();
      hello_aligned_ = true;
    }
    lock.unlock();
    if (!hello.empty()) server_->publish(ViewerChannel::kHello, std::move(hello), false);
    if (!stats.empty()) server_->publish(ViewerChannel::kStats, std::move(stats), false);
    {
      std::lock_guard<std::mutex> system_lock(system_mutex_);
      if (system_ && frame) {
        send_frame(*frame, *system_);
        ++frames_sent_;
      }
      if (system_ && map_due) {
        server_->publish(ViewerChannel::kMap, map_message(*system_), true);
        ++maps_sent_;
        send_occupancy(*system_);
        last_map = now;
      }
    }
    lock.lock();
  }
}

nlohmann::json Viewer::summary() const {
  const ViewerServerStats s = server_->stats();
  std::lock_guard<std::mutex> lock(mutex_);
  return {{"url", url()},
          {"frames_sent", frames_sent_.load()},
          {"maps_sent", maps_sent_.load()},
          {"occupancy_sent", occupancy_sent_.load()},
          {"connections", s.connections},
          {"clients_max", s.clients_max},
          {"messages_sent", s.messages_sent},
          {"messages_dropped", s.messages_dropped},
          {"clients_dropped", s.clients_dropped}};
}

}  // namespace mcslam::app
