#include "map_quality.hpp"

#include <array>
#include <cmath>
#include <fstream>
#include <limits>
#include <set>

#include "mcslam/core/error.hpp"
#include "mcslam/mapping/evaluation.hpp"

namespace mcslam::app {
namespace {

Eigen::Vector3d vector3(const nlohmann::json& j) {
  if (!j.is_array() || j.size() != 3) throw std::runtime_error("a 3-vector expected");
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

SE3 pose_of(const nlohmann::json& j) {
  if (!j.is_array() || j.size() != 7) throw std::runtime_error("a pose of 7 numbers expected");
  const Eigen::Quaterniond q(j[6].get<double>(), j[3].get<double>(), j[4].get<double>(),
                             j[5].get<double>());
  if (!(std::abs(q.norm() - 1.0) < 1e-3))
    throw std::runtime_error("a pose's quaternion is not unit");
  return SE3(q, Eigen::Vector3d(j[0].get<double>(), j[1].get<double>(), j[2].get<double>()));
}

/// The index of the frame whose timestamp is nearest to t.
std::size_t nearest_frame(const nlohmann::json& frames, double t) {
  std::size_t best = 0;
  double best_dt = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const double dt = std::abs(frames[k].at("timestamp").get<double>() - t);
    if (dt < best_dt) {
      best_dt = dt;
      best = k;
    }
  }
  return best;
}

SyntheticScene parse_scene(const nlohmann::json& j, double t_first, double t_last) {
  SyntheticScene scene;
  const nlohmann::json& room = j.at("room");
  scene.room_min = vector3(room.at("min"));
  scene.room_max = vector3(room.at("max"));
  if (!(scene.room_min.array() < scene.room_max.array()).all())
    throw std::runtime_error("the room's min corner is not below its max corner");
  const nlohmann::json& frames = j.at("frames");
  if (!frames.is_array() || frames.empty()) throw std::runtime_error("no frames");
  const nlohmann::json& first = frames[nearest_frame(frames, t_first)].at("objects");
  const nlohmann::json& last = frames[nearest_frame(frames, t_last)].at("objects");
  const nlohmann::json& objects = j.at("objects");
  if (first.size() != objects.size() || last.size() != objects.size())
    throw std::runtime_error("a frame does not list every object");
  for (std::size_t k = 0; k < objects.size(); ++k) {
    SyntheticScene::Object o;
    o.class_name = objects[k].at("class").get<std::string>();
    o.motion = objects[k].at("motion").get<std::string>();
    o.half_size = 0.5 * vector3(objects[k].at("size"));
    o.first = pose_of(first[k].at("pose"));
    o.last = pose_of(last[k].at("pose"));
    scene.objects.push_back(std::move(o));
  }
  return scene;
}

/// The voxels (of the map's resolution, in the run's frame) whose centre-sampled points lie in
/// the object's first box, above the floor's voxel and farther than a voxel from its final box.
nlohmann::json first_place(const mapping::OccupancyMap& map, const SyntheticScene& scene,
                           const SyntheticScene::Object& o, const SE3& T_est_gt) {
  const double res = map.options().resolution;
  const mapping::StaticSurface final_box = mapping::StaticSurface::box(o.last, o.half_size);
  std::set<std::array<long, 3>> seen;
  std::size_t occupied = 0, free = 0, unknown = 0;
  const Eigen::Vector3d h = o.half_size;
  for (double x = -h.x(); x <= h.x() + 1e-9; x += 0.5 * res) {
    for (double y = -h.y(); y <= h.y() + 1e-9; y += 0.5 * res) {
      for (double z = -h.z(); z <= h.z() + 1e-9; z += 0.5 * res) {
        const Eigen::Vector3d p_gt = o.first * Eigen::Vector3d(x, y, z);
        if (p_gt.z() < scene.room_min.z() + 1.5 * res) continue;  // the floor's own voxels
        const Eigen::Vector3d inside = o.last.inverse() * p_gt;
        const bool in_final = (inside.cwiseAbs() - h).maxCoeff() <= 0.0;
        if (in_final || (final_box.closest_point(p_gt) - p_gt).norm() <= res) continue;
        const Eigen::Vector3d p = T_est_gt * p_gt;
        const std::array<long, 3> key = {std::lround(std::floor(p.x() / res)),
                                         std::lround(std::floor(p.y() / res)),
                                         std::lround(std::floor(p.z() / res))};
        if (!seen.insert(key).second) continue;
        const Eigen::Vector3d centre =
            (Eigen::Vector3d(key[0], key[1], key[2]).array() + 0.5) * res;
        switch (map.state(centre)) {
          case mapping::VoxelState::kOccupied:
            ++occupied;
            break;
          case mapping::VoxelState::kFree:
            ++free;
            break;
          case mapping::VoxelState::kUnknown:
            ++unknown;
            break;
        }
      }
    }
  }
  return {{"voxels", seen.size()}, {"occupied", occupied}, {"free", free}, {"unknown", unknown}};
}

}  // namespace

std::optional<SyntheticScene> read_synthetic_scene(const std::filesystem::path& path,
                                                   double t_first, double t_last) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return std::nullopt;
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot open");
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_discarded()) throw InputError(path.string() + ": not valid JSON");
  if (!j.is_object() || j.value("format", std::string()) != "mcslam-synth-objects")
    return std::nullopt;
  if (!j.contains("room"))
    throw InputError(path.string() +
                     ": no \"room\" (written by an mcslam synth before the map's evaluation: "
                     "render the sequence again)");
  try {
    return parse_scene(j, t_first, t_last);
  } catch (const std::exception& e) {
    throw InputError(path.string() + ": " + e.what());
  }
}

nlohmann::json evaluate_synthetic_map(const mapping::OccupancyMap& map, const SyntheticScene& scene,
                                      const SE3& T_est_gt) {
  // The room is a box seen from inside: its walls, floor and ceiling end where they meet.
  std::vector<mapping::StaticSurface> surfaces = {mapping::StaticSurface::box(
      T_est_gt * SE3(Eigen::Quaterniond::Identity(), 0.5 * (scene.room_min + scene.room_max)),
      0.5 * (scene.room_max - scene.room_min))};
  nlohmann::json movers = nlohmann::json::array();
  for (const SyntheticScene::Object& o : scene.objects) {
    if (o.motion == "free") continue;  // people: never a static surface
    const SE3 pose = o.motion == "slide" ? o.last : o.first;
    surfaces.push_back(mapping::StaticSurface::box(T_est_gt * pose, o.half_size));
    if (o.motion != "slide") continue;
    const mapping::MapQuality final_place =
        mapping::evaluate_map(map, {mapping::StaticSurface::box(T_est_gt * o.last, o.half_size)});
    movers.push_back({{"class", o.class_name},
                      {"moved_m", (o.last.translation() - o.first.translation()).norm()},
                      {"first_place", first_place(map, scene, o, T_est_gt)},
                      {"final_place",
                       {{"surface_seen", final_place.surface_seen},
                        {"surface_occupied", final_place.surface_occupied},
                        {"occupied_ratio", final_place.completeness}}}});
  }
  const mapping::MapQuality q = mapping::evaluate_map(map, surfaces);
  return {{"ghost_rate", q.ghost_rate},
          {"ghosts", q.ghosts},
          {"occupied", q.occupied},
          {"completeness", q.completeness},
          {"surface_seen", q.surface_seen},
          {"surface_occupied", q.surface_occupied},
          {"movers", movers}};
}

}  // namespace mcslam::app
