#include "mcslam/map/export.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <vector>

namespace mcslam::map {
namespace {

template <typename Table>
std::vector<std::uint64_t> sorted_ids(const Table& table) {
  std::vector<std::uint64_t> ids;
  ids.reserve(table.size());
  for (const auto& kv : table) ids.push_back(kv.first);
  std::sort(ids.begin(), ids.end());
  return ids;
}

/// A distinct, stable colour per plane id (golden-ratio hue steps).
std::array<int, 3> plane_color(std::uint64_t id) {
  const double hue = std::fmod(0.13 + 0.618033988749895 * static_cast<double>(id), 1.0) * 6.0;
  const int sector = static_cast<int>(hue);
  const double f = hue - sector;
  const double v = 0.9, s = 0.55;
  const double p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
  double r = v, g = t, b = p;
  switch (sector % 6) {
    case 1:
      r = q;
      g = v;
      b = p;
      break;
    case 2:
      r = p;
      g = v;
      b = t;
      break;
    case 3:
      r = p;
      g = q;
      b = v;
      break;
    case 4:
      r = t;
      g = p;
      b = v;
      break;
    case 5:
      r = v;
      g = p;
      b = q;
      break;
    default:
      break;
  }
  return {static_cast<int>(255 * r), static_cast<int>(255 * g), static_cast<int>(255 * b)};
}

nlohmann::json vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json observations(const std::map<KeyFrameId, int>& obs) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& [kf, index] : obs) out.push_back({kf, index});
  return out;
}

}  // namespace

std::string map_to_ply(const Map& map) {
  std::ostringstream vertices, edges, faces;
  vertices << std::fixed << std::setprecision(5);
  std::size_t n_vertices = 0, n_edges = 0, n_faces = 0;
  const auto add_vertex = [&](const Eigen::Vector3d& p, int r, int g, int b) {
    vertices << p.x() << ' ' << p.y() << ' ' << p.z() << ' ' << r << ' ' << g << ' ' << b << '\n';
    return n_vertices++;
  };
  for (std::uint64_t id : sorted_ids(map.points())) {
    const MapPoint& mp = map.points().at(id);
    add_vertex(mp.p_w, mp.color[0], mp.color[1], mp.color[2]);
  }
  for (std::uint64_t id : sorted_ids(map.lines())) {
    const MapLine& ml = map.lines().at(id);
    const std::size_t a = add_vertex(ml.start_w, 220, 30, 30);
    const std::size_t b = add_vertex(ml.end_w, 220, 30, 30);
    edges << a << ' ' << b << " 220 30 30\n";
    ++n_edges;
  }
  for (std::uint64_t id : sorted_ids(map.planes())) {
    const MapPlane& mp = map.planes().at(id);
    if (mp.hull.size() < 3) continue;
    const auto c = plane_color(id);
    faces << mp.hull.size();
    for (const auto& corner : mp.hull) faces << ' ' << add_vertex(corner, c[0], c[1], c[2]);
    faces << ' ' << c[0] << ' ' << c[1] << ' ' << c[2] << '\n';
    ++n_faces;
  }
  for (std::uint64_t id : sorted_ids(map.keyframes()))
    add_vertex(map.keyframes().at(id).camera_center(), 30, 90, 230);

  std::ostringstream ply;
  ply << "ply\nformat ascii 1.0\ncomment mcslam map: points, line segments (edges), planes "
         "(faces), keyframe centres (blue)\n"
      << "element vertex " << n_vertices
      << "\nproperty float x\nproperty float y\nproperty float z\n"
         "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      << "element edge " << n_edges
      << "\nproperty int vertex1\nproperty int vertex2\n"
         "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      << "element face " << n_faces
      << "\nproperty list uchar int vertex_indices\n"
         "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
      << vertices.str() << edges.str() << faces.str();
  return ply.str();
}

nlohmann::json map_to_json(const Map& map) {
  nlohmann::json out;
  out["keyframes"] = nlohmann::json::array();
  for (std::uint64_t id : sorted_ids(map.keyframes())) {
    const KeyFrame& kf = map.keyframes().at(id);
    const SE3 T_w_c = kf.T_w_c();
    const auto& q = T_w_c.quaternion();
    out["keyframes"].push_back({{"id", id},
                                {"frame", kf.frame_id},
                                {"timestamp", kf.timestamp},
                                {"t_w_c", vec(T_w_c.translation())},
                                {"q_w_c_xyzw", {q.x(), q.y(), q.z(), q.w()}}});
  }
  out["points"] = nlohmann::json::array();
  for (std::uint64_t id : sorted_ids(map.points())) {
    const MapPoint& mp = map.points().at(id);
    out["points"].push_back({{"id", id},
                             {"p_w", vec(mp.p_w)},
                             {"color_rgb", {mp.color[0], mp.color[1], mp.color[2]}},
                             {"observations", observations(mp.observations)}});
  }
  out["lines"] = nlohmann::json::array();
  for (std::uint64_t id : sorted_ids(map.lines())) {
    const MapLine& ml = map.lines().at(id);
    out["lines"].push_back({{"id", id},
                            {"start_w", vec(ml.start_w)},
                            {"end_w", vec(ml.end_w)},
                            {"observations", observations(ml.observations)}});
  }
  out["planes"] = nlohmann::json::array();
  for (std::uint64_t id : sorted_ids(map.planes())) {
    const MapPlane& mp = map.planes().at(id);
    nlohmann::json hull = nlohmann::json::array();
    for (const auto& h : mp.hull) hull.push_back(vec(h));
    out["planes"].push_back({{"id", id},
                             {"normal", vec(mp.normal)},
                             {"d", mp.d},
                             {"hull_w", hull},
                             {"observations", observations(mp.observations)}});
  }
  out["observation_format"] = "[keyframe id, feature index in that keyframe]";
  return out;
}

}  // namespace mcslam::map
