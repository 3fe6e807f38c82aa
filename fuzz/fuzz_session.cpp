// Fuzzes the session file reader (map/session.hpp). The first byte chooses how the rest is read:
// as the whole file (checksum included, so corrupt files are rejected by it), or as a file body to
// which the valid checksum is appended (so the structure and consistency checks behind the
// checksum are reached). A file that loads must save back to the very same bytes, and its map
// must stand the map's own updates (covisibility, appearance, culling a keyframe).
#include <algorithm>
#include <fstream>
#include <iterator>
#include <vector>

#include "fuzz_support.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/map/session.hpp"
#include "mcslam/place/vocabulary.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mcslam;
  if (size == 0) return 0;
  std::string bytes(fuzz::as_text(data + 1, size - 1));
  if (data[0] & 1) {
    const std::uint64_t sum = place::file_checksum(bytes);
    bytes.append(reinterpret_cast<const char*>(&sum), sizeof(sum));
  }
  const std::string path = fuzz::write("map.session", bytes);
  map::Session session;
  try {
    session = map::load_session(path);
  } catch (const InputError&) {
    return 0;
  }
  map::Map& m = *session.map;
  // Everything is stored exactly and in one order: what loads saves back unchanged.
  const std::string copy = (fuzz::scratch() / "copy.session").string();
  map::save_session(copy, m, session.info);
  std::ifstream in(copy, std::ios::binary);
  const std::string saved((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (saved != bytes) __builtin_trap();

  std::vector<map::KeyFrameId> keyframes;
  for (const auto& entry : m.keyframes()) keyframes.push_back(entry.first);
  std::sort(keyframes.begin(), keyframes.end());
  std::vector<map::PointId> points;
  for (const auto& entry : m.points()) points.push_back(entry.first);
  std::sort(points.begin(), points.end());
  std::vector<map::LineId> lines;
  for (const auto& entry : m.lines()) lines.push_back(entry.first);
  std::sort(lines.begin(), lines.end());
  for (const map::PointId id : points) m.update_point_appearance(id);
  for (const map::LineId id : lines) m.update_line_appearance(id);
  for (const map::KeyFrameId id : keyframes) {
    (void)m.best_covisible(id, 5);
    (void)m.keyframe_pose_T_c_w(id);
  }
  for (const auto& entry : m.erased_keyframes()) (void)m.keyframe_pose_T_c_w(entry.first);
  if (!keyframes.empty()) m.erase_keyframe(keyframes.front());
  for (const map::KeyFrameId id : keyframes) m.update_covisibility(id);
  return 0;
}
