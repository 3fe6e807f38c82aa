#pragma once
// Session files: the whole map (keyframes with their features, point, line and plane landmarks,
// covisibility, culled keyframes, id counters) in one binary file, so that a later run can start
// from it.
//
// The format is little-endian binary: "MCSLSES\0", a uint32 format version (3), the body, and
// the FNV-1a 64-bit checksum (place::file_checksum) of everything before it. The body holds the
// SessionInfo, the map's counters, then the keyframes, points, lines, planes, culled keyframes
// and the dense map's keyframe samples, each list sorted by id (so that one map always gives
// the same bytes). Keypoint grids and scale pyramids are not stored: they are rebuilt on load
// from the camera and the ORB pyramid options of the SessionInfo. The file is read back exactly:
// ids, links, counters and every number (poses included) are what was saved, and saving a loaded
// map gives the same bytes.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/map/map.hpp"
#include "mcslam/mapping/occupancy_map.hpp"

namespace mcslam::map {

/// What a session must match to be reused.
struct SessionInfo {
  /// Intrinsics, image size, distortion, depth factor, bf and readout time.
  PinholeCamera camera;
  /// place::Vocabulary::id() of the vocabulary the map was built with (0: none).
  std::uint64_t vocabulary_id = 0;
  /// The ORB pyramid of every keyframe's features (rebuilt on load).
  int orb_levels = 8;
  double orb_scale_factor = 1.2;
};

/// Writes the whole map atomically (a temporary file in the same folder, then renamed), and the
/// dense map's stored keyframe samples (mapping::OccupancyMap::keyframes(), in increasing id
/// order; about 0.2 MB a VGA keyframe), from which the dense map is rebuilt on load. Call it
/// under map.read_lock() while another thread may write the map. Throws InputError
/// "<path>: <problem>" when the file cannot be written, or when the map, the info or the dense
/// samples could not be read back (an invalid camera or pyramid, a non-finite number, a link
/// that does not resolve): a file that is written always loads.
void save_session(const std::string& path, const Map& map, const SessionInfo& info,
                  const std::vector<mapping::KeyframeSamples>& dense = {});

struct Session {
  SessionInfo info;
  std::unique_ptr<Map> map;
  /// The dense map's keyframes (mapping::OccupancyMap::insert(KeyframeSamples) rebuilds it).
  std::vector<mapping::KeyframeSamples> dense;
};

/// Reads a file written by save_session. Throws InputError "<path>: <problem>" (one clear
/// message) for a missing, empty, truncated, foreign (wrong magic), wrong-version, corrupt
/// (checksum mismatch) or inconsistent file (ids that do not resolve, counts out of range, sizes
/// that do not match, non-finite numbers).
Session load_session(const std::string& path);

}  // namespace mcslam::map
