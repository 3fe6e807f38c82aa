#include "mcslam/app/bench/report.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>

#include "mcslam/core/error.hpp"

namespace mcslam::app::bench {
namespace fs = std::filesystem;

namespace {

/// Indices 0..n-1 thinned evenly to at most `max` (first and last kept).
std::vector<std::size_t> thinned(std::size_t n, std::size_t max) {
  std::vector<std::size_t> idx;
  if (n == 0 || max == 0) return idx;
  if (n <= max) {
    for (std::size_t i = 0; i < n; ++i) idx.push_back(i);
    return idx;
  }
  for (std::size_t k = 0; k < max; ++k) idx.push_back(max == 1 ? 0 : k * (n - 1) / (max - 1));
  return idx;
}

double round_to(double v, double step) { return std::round(v / step) * step; }

nlohmann::json xyz(const Eigen::Vector3d& p) {
  // Millimetres are plenty for plots and keep the page small.
  return {round_to(p.x(), 1e-4), round_to(p.y(), 1e-4), round_to(p.z(), 1e-4)};
}

nlohmann::json load_json(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError(file_error(path.string(), "missing"));
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(file_error(path.string(), std::string("not JSON: ") + e.what()));
  }
}

Eigen::Vector3d vec3(const nlohmann::json& a) {
  return {a.at(0).get<double>(), a.at(1).get<double>(), a.at(2).get<double>()};
}

/// The objects of a frame that moved, as "person dynamic, chair constrained".
std::string moving_objects(const nlohmann::json& frame, bool& any) {
  std::ostringstream s;
  any = false;
  for (const auto& o : frame.value("objects", nlohmann::json::array())) {
    const std::string state = o.value("state", "");
    if (state != "dynamic" && state != "constrained") continue;
    s << (any ? ", " : "") << o.value("class", "object") << ' ' << state;
    any = true;
  }
  return s.str();
}

}  // namespace

nlohmann::json groundtruth_json(const Trajectory& groundtruth, double t0, double t1,
                                std::size_t max_poses) {
  std::vector<const StampedPose*> kept;
  for (const StampedPose& p : groundtruth)
    if (t0 > t1 || (p.timestamp >= t0 && p.timestamp <= t1)) kept.push_back(&p);
  nlohmann::json t = nlohmann::json::array(), pos = nlohmann::json::array();
  for (std::size_t i : thinned(kept.size(), max_poses)) {
    t.push_back(kept[i]->timestamp);
    pos.push_back(xyz(kept[i]->T_w_c.translation()));
  }
  return {{"t", t}, {"p", pos}};
}

nlohmann::json trajectory_json(const Trajectory& estimate, const eval::EvalReport* report,
                               std::size_t max_poses) {
  nlohmann::json t = nlohmann::json::array(), pos = nlohmann::json::array(),
                 err = nlohmann::json::array();
  if (report && !report->ate.timestamps.empty()) {
    std::map<double, Eigen::Vector3d> by_time;
    for (const StampedPose& p : estimate) by_time[p.timestamp] = p.T_w_c.translation();
    const auto& stamps = report->ate.timestamps;
    for (std::size_t i : thinned(stamps.size(), max_poses)) {
      const auto it = by_time.find(stamps[i]);
      if (it == by_time.end()) continue;
      t.push_back(stamps[i]);
      pos.push_back(xyz(report->ate.T_gt_est * it->second));
      err.push_back(round_to(report->ate.errors[i], 1e-5));
    }
    return {{"t", t}, {"p", pos}, {"ate_error_m", err}};
  }
  for (std::size_t i : thinned(estimate.size(), max_poses)) {
    t.push_back(estimate[i].timestamp);
    pos.push_back(xyz(estimate[i].T_w_c.translation()));
  }
  return {{"t", t}, {"p", pos}, {"ate_error_m", nullptr}};
}

nlohmann::json map_json(const std::string& map_json_path, std::size_t max_points) {
  const nlohmann::json map = load_json(map_json_path);
  nlohmann::json out;
  try {
    nlohmann::json points = nlohmann::json::array(), colors = nlohmann::json::array();
    const auto& all = map.at("points");
    for (std::size_t i : thinned(all.size(), max_points)) {
      const auto& p = all[i];
      for (double v : xyz(vec3(p.at("p_w")))) points.push_back(v);
      if (p.contains("color_rgb"))
        for (const auto& c : p["color_rgb"]) colors.push_back(c.get<int>());
    }
    nlohmann::json lines = nlohmann::json::array();
    for (const auto& l : map.at("lines")) {
      for (double v : xyz(vec3(l.at("start_w")))) lines.push_back(v);
      for (double v : xyz(vec3(l.at("end_w")))) lines.push_back(v);
    }
    nlohmann::json planes = nlohmann::json::array();
    for (const auto& pl : map.at("planes")) {
      nlohmann::json hull = nlohmann::json::array();
      for (const auto& c : pl.at("hull_w")) hull.push_back(xyz(vec3(c)));
      planes.push_back({{"normal", pl.at("normal")}, {"d", pl.at("d")}, {"hull", hull}});
    }
    nlohmann::json keyframes = nlohmann::json::array();
    for (const auto& k : map.at("keyframes")) keyframes.push_back(xyz(vec3(k.at("t_w_c"))));
    out = {{"points", points},
           {"colors", colors.size() == points.size() ? colors : nlohmann::json(nullptr)},
           {"lines", lines},
           {"planes", planes},
           {"keyframes", keyframes}};
  } catch (const nlohmann::json::exception& e) {
    throw InputError(file_error(map_json_path, std::string("unexpected content: ") + e.what()));
  }
  return out;
}

nlohmann::json overlays_json(const std::string& run_dir, int count, int width) {
  nlohmann::json out = nlohmann::json::array();
  const fs::path dir = fs::path(run_dir) / "overlays";
  std::error_code ec;
  if (count <= 0 || !fs::is_directory(dir, ec)) return out;
  std::vector<long> frames;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().extension() == ".jpg") {
      try {
        frames.push_back(std::stol(e.path().stem().string()));
      } catch (const std::exception&) {
      }
    }
  std::sort(frames.begin(), frames.end());
  if (frames.empty()) return out;

  // Frames where objects moved, with their captions, from objects.json (when there is one).
  std::map<long, std::string> moving;
  std::map<long, double> stamps;
  if (fs::exists(fs::path(run_dir) / "objects.json")) {
    try {
      const nlohmann::json objects = load_json(fs::path(run_dir) / "objects.json");
      for (const auto& f : objects.at("frames")) {
        const long id = f.at("frame").get<long>();
        stamps[id] = f.value("timestamp", 0.0);
        bool any = false;
        const std::string text = moving_objects(f, any);
        if (any) moving[id] = text;
      }
    } catch (const std::exception&) {
      moving.clear();  // captions are a nicety; the frames still show
    }
  }
  std::set<long> chosen;
  std::vector<long> with_motion;
  for (long f : frames)
    if (moving.count(f)) with_motion.push_back(f);
  const std::size_t half = with_motion.size() >= static_cast<std::size_t>(count / 2)
                               ? static_cast<std::size_t>(count / 2)
                               : with_motion.size();
  for (std::size_t i : thinned(with_motion.size(), half)) chosen.insert(with_motion[i]);
  // The rest spread over the run, leaving out its very first and last frames.
  const std::size_t rest = static_cast<std::size_t>(count) - chosen.size();
  for (std::size_t i : thinned(frames.size(), rest + 2)) {
    if (chosen.size() >= static_cast<std::size_t>(count)) break;
    if (frames.size() > 2 && (i == 0 || i + 1 == frames.size())) continue;
    chosen.insert(frames[i]);
  }

  for (long f : chosen) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06ld.jpg", f);
    const cv::Mat image = cv::imread((dir / name).string(), cv::IMREAD_COLOR);
    if (image.empty()) continue;
    cv::Mat small = image;
    if (image.cols > width)
      cv::resize(image, small, cv::Size(width, image.rows * width / image.cols), 0, 0,
                 cv::INTER_AREA);
    std::vector<unsigned char> jpeg;
    if (!cv::imencode(".jpg", small, jpeg, {cv::IMWRITE_JPEG_QUALITY, 82})) continue;
    std::string caption = "frame " + std::to_string(f);
    if (moving.count(f)) caption += " · " + moving[f];
    out.push_back({{"frame", f},
                   {"timestamp", stamps.count(f) ? nlohmann::json(stamps[f]) : nlohmann::json()},
                   {"caption", caption},
                   {"jpeg_base64", base64(jpeg.data(), jpeg.size())}});
  }
  return out;
}

nlohmann::json grid_json(const std::string& run_dir) {
  const fs::path png = fs::path(run_dir) / "grid.png";
  std::ifstream in(png, std::ios::binary);
  if (!in) return nullptr;
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.empty()) return nullptr;
  nlohmann::json j = {
      {"png_base64", base64(reinterpret_cast<const unsigned char*>(bytes.data()), bytes.size())}};
  try {
    const nlohmann::json summary = load_json(fs::path(run_dir) / "summary.json");
    if (summary.contains("occupancy")) j["occupancy"] = summary["occupancy"];
  } catch (const std::exception&) {
    // the picture alone
  }
  return j;
}

std::string base64(const unsigned char* data, std::size_t size) {
  static constexpr char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((size + 2) / 3 * 4);
  for (std::size_t i = 0; i < size; i += 3) {
    const unsigned v =
        (data[i] << 16) | (i + 1 < size ? data[i + 1] << 8 : 0) | (i + 2 < size ? data[i + 2] : 0);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += i + 1 < size ? kAlphabet[(v >> 6) & 63] : '=';
    out += i + 2 < size ? kAlphabet[v & 63] : '=';
  }
  return out;
}

std::string report_html(const nlohmann::json& data, const std::string& bundle_js) {
  std::string json = data.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  std::string safe_json;
  safe_json.reserve(json.size());
  for (char c : json) {
    if (c == '<')
      safe_json += "\\u003c";  // only inside strings: valid JSON, and ends no script
    else
      safe_json += c;
  }
  std::string js = bundle_js;
  for (std::size_t at = 0; (at = js.find("</script", at)) != std::string::npos; at += 2)
    js.replace(at, 2, "<\\/");
  std::ostringstream html;
  html << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
          "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
          "<title>mcslam bench report</title>\n</head>\n<body>\n"
          "<noscript>This report needs JavaScript. The same tables are in results.md next to "
          "this file.</noscript>\n"
          "<script id=\"mcslam-data\" type=\"application/json\">"
       << safe_json << "</script>\n<script>" << js << "</script>\n</body>\n</html>\n";
  return html.str();
}

}  // namespace mcslam::app::bench
