#pragma once
// The map as files a person can open: a PLY (coloured points, line segments as edges, planes as
// filled polygons) for MeshLab / CloudCompare / Open3D, and a JSON with every landmark's id,
// geometry and observations (keyframe id and feature index) for programs.
//
// Both are built from a consistent view of the map: call them under map.read_lock() while the
// system runs threaded.

#include <nlohmann/json.hpp>
#include <string>

#include "mcslam/map/map.hpp"

namespace mcslam::map {

/// ASCII PLY. Elements: vertex (x, y, z, red, green, blue), edge (vertex1, vertex2, red, green,
/// blue) and face (vertex_indices, red, green, blue). Vertices are the points first, then the
/// two endpoints of each line, then the hull corners of each plane (its face), and the camera
/// centres of the keyframes (no edges). Ids are sorted, so the output is deterministic.
std::string map_to_ply(const Map& map);

/// {"keyframes": [{id, timestamp, T_w_c: {t, q_xyzw}}], "points": [{id, p_w, color,
/// observations: [[keyframe, index], ...]}], "lines": [{id, start_w, end_w, observations}],
/// "planes": [{id, normal, d, hull, observations}]}.
nlohmann::json map_to_json(const Map& map);

}  // namespace mcslam::map
