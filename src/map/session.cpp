#include "mcslam/map/session.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <optional>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/io/files.hpp"
#include "mcslam/place/vocabulary.hpp"

namespace mcslam::map {
namespace {

static_assert(std::endian::native == std::endian::little,
              "session files are little-endian and written with memcpy");

constexpr char kMagic[8] = {'M', 'C', 'S', 'L', 'S', 'E', 'S', '\0'};
/// 2: line descriptors are mcslam's own LBD (line_band_descriptor.hpp), no longer OpenCV's; a
/// version 1 file's lines would match nothing, so it is refused rather than half used.
/// 3: the dense map's keyframe samples follow the culled keyframes (a version 2 file has no
/// dense map to rebuild: refused with a message that says so).
constexpr std::uint32_t kFormatVersion = 3;
constexpr std::size_t kHeaderBytes = sizeof(kMagic) + sizeof(std::uint32_t);
constexpr std::size_t kChecksumBytes = sizeof(std::uint64_t);

// Limits of what a session may hold (beyond them the file is refused as inconsistent).
constexpr int kMaxImageSide = 16384;  // a keypoint grid is rebuilt per keyframe from the size
constexpr int kMaxOrbLevels = 16;     // as OrbOptions::check
constexpr double kMaxScaleFactor = 4.0;
/// Largest | |q|^2 - 1 | of a saved rotation: SE3 keeps its quaternions unit to a few ulps.
constexpr double kUnitTolerance = 1e-12;

// Bytes in the file of the fixed-size records, and the least bytes of the variable-size ones:
// a count read from the file is refused when that many elements cannot fit in the bytes left.
constexpr std::size_t kU64 = 8;
constexpr std::size_t kU32 = 4;
constexpr std::size_t kF64 = 8;
constexpr std::size_t kF32 = 4;
constexpr std::size_t kDescriptorBytes = 32;
constexpr std::size_t kVector3Bytes = 3 * kF64;
constexpr std::size_t kPoseBytes = 7 * kF64;     // quaternion w, x, y, z; translation x, y, z
constexpr std::size_t kLinkBytes = kU64 + kU32;  // (keyframe id, int): observation, covisibility
constexpr std::size_t kPointFeatureBytes =
    2 * kF32 + kU32 + 2 * kF32 + kDescriptorBytes + 2 * kF32 + kU32;
constexpr std::size_t kLineFeatureBytes = 4 * kF32 + kDescriptorBytes + 1 + 2 * kVector3Bytes;
constexpr std::size_t kPlaneFeatureMinBytes = 2 * kVector3Bytes + kF64 + kU32 + kF64 + kU64;
constexpr std::size_t kKeyFrameMinBytes = 3 * kU64 + kPoseBytes + 9 * kU64;
constexpr std::size_t kMapPointMinBytes =
    kU64 + kVector3Bytes + kDescriptorBytes + kU64 + kVector3Bytes + 2 * kF64 + kU64 + 3 + 2 * kU32;
constexpr std::size_t kMapLineMinBytes =
    kU64 + 2 * kVector3Bytes + kDescriptorBytes + kU64 + kU64 + 2 * kU32;
constexpr std::size_t kMapPlaneMinBytes = kU64 + kVector3Bytes + kF64 + kU64 + kU64 + kU64;
constexpr std::size_t kErasedBytes = 2 * kU64 + kPoseBytes;
constexpr std::size_t kDenseMinBytes = kU64 + kPoseBytes + 4 * kF64 + 5 * kU32 + 1;

// --- writing ---

class Writer {
 public:
  template <typename T>
  void put(T value) {
    static_assert(std::is_arithmetic_v<T>);
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    out_.append(bytes, sizeof(T));
  }
  void count(std::size_t n) { put<std::uint64_t>(n); }
  void vec2(const Eigen::Vector2f& v) {
    put<float>(v.x());
    put<float>(v.y());
  }
  void vec3(const Eigen::Vector3d& v) {
    put<double>(v.x());
    put<double>(v.y());
    put<double>(v.z());
  }
  void descriptor(const features::OrbDescriptor& d) {
    out_.append(reinterpret_cast<const char*>(d.bytes.data()), d.bytes.size());
  }
  void pose(const SE3& T) {
    const Eigen::Quaterniond& q = T.quaternion();
    put<double>(q.w());
    put<double>(q.x());
    put<double>(q.y());
    put<double>(q.z());
    vec3(T.translation());
  }
  void links(const std::map<KeyFrameId, int>& links) {
    count(links.size());
    for (const auto& [keyframe, value] : links) {
      put<std::uint64_t>(keyframe);
      put<std::int32_t>(value);
    }
  }
  void hull(const std::vector<Eigen::Vector3d>& hull) {
    count(hull.size());
    for (const auto& p : hull) vec3(p);
  }
  template <typename Id>
  void ids(const std::vector<Id>& ids) {
    count(ids.size());
    for (Id id : ids) put<std::uint64_t>(id);
  }
  void flags(const std::vector<std::uint8_t>& flags) {
    count(flags.size());
    out_.append(flags.begin(), flags.end());
  }
  /// A continuous matrix's bytes (row by row).
  void matrix(const cv::Mat& m) {
    for (int row = 0; row < m.rows; ++row) out_.append(m.ptr<char>(row), m.cols * m.elemSize());
  }
  std::string& bytes() { return out_; }

 private:
  std::string out_;
};

void write_dense_keyframe(Writer& w, const mapping::KeyframeSamples& kf) {
  w.put<std::uint64_t>(kf.id);
  w.pose(kf.T_w_c);
  w.put<double>(kf.camera.fx);
  w.put<double>(kf.camera.fy);
  w.put<double>(kf.camera.cx);
  w.put<double>(kf.camera.cy);
  w.put<std::int32_t>(kf.camera.width);
  w.put<std::int32_t>(kf.camera.height);
  w.put<std::int32_t>(kf.step);
  w.put<std::int32_t>(kf.depth_mm.rows);
  w.put<std::int32_t>(kf.depth_mm.cols);
  w.matrix(kf.depth_mm);
  w.matrix(kf.kind);
  w.put<std::uint8_t>(kf.colour.empty() ? 0 : 1);
  if (!kf.colour.empty()) w.matrix(kf.colour);
}

void write_info(Writer& w, const SessionInfo& info) {
  const PinholeCamera& c = info.camera;
  w.put<double>(c.fx);
  w.put<double>(c.fy);
  w.put<double>(c.cx);
  w.put<double>(c.cy);
  w.put<std::int32_t>(c.width);
  w.put<std::int32_t>(c.height);
  for (double d : c.distortion) w.put<double>(d);
  w.put<double>(c.depth_factor);
  w.put<double>(c.bf);
  w.put<double>(c.readout_time);
  w.put<std::uint64_t>(info.vocabulary_id);
  w.put<std::int32_t>(info.orb_levels);
  w.put<double>(info.orb_scale_factor);
}

void write_features(Writer& w, const features::FrameFeatures& f) {
  w.count(f.points.size());
  for (const auto& p : f.points) {
    w.vec2(p.keypoint.uv);
    w.put<std::int32_t>(p.keypoint.level);
    w.put<float>(p.keypoint.angle_deg);
    w.put<float>(p.keypoint.response);
    w.descriptor(p.descriptor);
    w.put<float>(p.depth);
    w.put<float>(p.u_right);
    w.put<std::int32_t>(p.plane);
  }
  w.count(f.lines.size());
  for (const auto& l : f.lines) {
    w.vec2(l.start);
    w.vec2(l.end);
    w.descriptor(l.descriptor);
    w.put<std::uint8_t>(l.has_depth ? 1 : 0);
    w.vec3(l.start_c);
    w.vec3(l.end_c);
  }
  w.count(f.planes.size());
  for (const auto& p : f.planes) {
    w.vec3(p.normal);
    w.put<double>(p.d);
    w.vec3(p.centroid);
    w.put<std::int32_t>(p.num_pixels);
    w.put<double>(p.rms);
    w.hull(p.hull);
  }
}

void write_keyframe(Writer& w, const KeyFrame& kf) {
  w.put<std::uint64_t>(kf.id);
  w.put<std::uint64_t>(kf.frame_id);
  w.put<double>(kf.timestamp);
  w.pose(kf.T_c_w);
  write_features(w, *kf.features);
  w.ids(kf.landmarks);
  w.ids(kf.line_landmarks);
  w.ids(kf.plane_landmarks);
  w.flags(kf.excluded_points);
  w.flags(kf.excluded_lines);
  std::vector<std::pair<KeyFrameId, int>> covisible(kf.covisibility.begin(), kf.covisibility.end());
  std::sort(covisible.begin(), covisible.end());
  w.count(covisible.size());
  for (const auto& [other, weight] : covisible) {
    w.put<std::uint64_t>(other);
    w.put<std::int32_t>(weight);
  }
  w.ids(std::vector<KeyFrameId>(kf.loop_edges.begin(), kf.loop_edges.end()));  // sorted (a set)
}

template <typename Element>
std::vector<std::uint64_t> sorted_ids(const std::unordered_map<std::uint64_t, Element>& elements) {
  std::vector<std::uint64_t> ids;
  ids.reserve(elements.size());
  for (const auto& entry : elements) ids.push_back(entry.first);
  std::sort(ids.begin(), ids.end());
  return ids;
}

// --- checks shared by saving and loading ---

bool unit(const Eigen::Quaterniond& q) {
  return q.coeffs().allFinite() && std::abs(q.squaredNorm() - 1.0) <= kUnitTolerance;
}

bool finite(const SE3& T) { return unit(T.quaternion()) && T.translation().allFinite(); }

bool finite(const std::vector<Eigen::Vector3d>& points) {
  return std::all_of(points.begin(), points.end(),
                     [](const Eigen::Vector3d& p) { return p.allFinite(); });
}

std::optional<std::string> check_info(const SessionInfo& info) {
  if (auto problem = info.camera.check()) return "camera: " + *problem;
  if (info.camera.width > kMaxImageSide || info.camera.height > kMaxImageSide)
    return "camera image size " + std::to_string(info.camera.width) + "x" +
           std::to_string(info.camera.height) + " is above " + std::to_string(kMaxImageSide);
  if (info.orb_levels < 1 || info.orb_levels > kMaxOrbLevels)
    return "ORB pyramid levels " + std::to_string(info.orb_levels) + " out of [1, " +
           std::to_string(kMaxOrbLevels) + "]";
  if (!(info.orb_scale_factor > 1.0 && info.orb_scale_factor <= kMaxScaleFactor))
    return "ORB pyramid scale factor out of (1, 4]";
  return std::nullopt;
}

std::string kf_name(KeyFrameId id) { return "keyframe " + std::to_string(id); }

std::optional<std::string> check_features(const features::FrameFeatures& f,
                                          const SessionInfo& info) {
  const int n_planes = static_cast<int>(f.planes.size());
  for (std::size_t i = 0; i < f.points.size(); ++i) {
    const auto& p = f.points[i];
    if (!p.keypoint.uv.allFinite() || !std::isfinite(p.keypoint.angle_deg) ||
        !std::isfinite(p.keypoint.response) || !std::isfinite(p.depth) || !std::isfinite(p.u_right))
      return "point feature " + std::to_string(i) + " has a non-finite number";
    if (p.keypoint.level < 0 || p.keypoint.level >= info.orb_levels)
      return "point feature " + std::to_string(i) + " is on pyramid level " +
             std::to_string(p.keypoint.level) + " (the pyramid has " +
             std::to_string(info.orb_levels) + " levels)";
    if (p.plane < -1 || p.plane >= n_planes)
      return "point feature " + std::to_string(i) + " lies on plane " + std::to_string(p.plane) +
             " (the keyframe has " + std::to_string(n_planes) + " planes)";
  }
  for (std::size_t i = 0; i < f.lines.size(); ++i) {
    const auto& l = f.lines[i];
    if (!l.start.allFinite() || !l.end.allFinite() || !l.start_c.allFinite() ||
        !l.end_c.allFinite())
      return "line feature " + std::to_string(i) + " has a non-finite number";
  }
  for (std::size_t i = 0; i < f.planes.size(); ++i) {
    const auto& p = f.planes[i];
    if (!p.normal.allFinite() || !std::isfinite(p.d) || !p.centroid.allFinite() ||
        !std::isfinite(p.rms) || !finite(p.hull))
      return "plane feature " + std::to_string(i) + " has a non-finite number";
  }
  return std::nullopt;
}

/// The observations of a landmark: every keyframe exists and the feature index is within its
/// `count_of(keyframe)` features.
template <typename CountOf>
std::optional<std::string> check_observations(const Map& map, const std::string& name,
                                              const std::map<KeyFrameId, int>& observations,
                                              CountOf count_of) {
  for (const auto& [kf_id, index] : observations) {
    const KeyFrame* kf = map.keyframe(kf_id);
    if (kf == nullptr) return name + " is observed by " + kf_name(kf_id) + ", not in the map";
    const std::size_t n = count_of(*kf);
    if (index < 0 || static_cast<std::size_t>(index) >= n)
      return name + " is observed by feature " + std::to_string(index) + " of " + kf_name(kf_id) +
             ", which has " + std::to_string(n);
  }
  return std::nullopt;
}

/// One keyframe: its id, features and pose, and every landmark, covisibility and loop edge it
/// links resolves.
std::optional<std::string> check_keyframe(const Map& map, KeyFrameId id, const SessionInfo& info) {
  const KeyFrame& kf = map.keyframes().at(id);
  const std::string name = kf_name(id);
  if (kf.id != id) return name + " is stored under id " + std::to_string(kf.id);
  if (id == kNoId) return "a keyframe has no id";
  if (kf.features == nullptr) return name + " has no features";
  const features::FrameFeatures& f = *kf.features;
  if (!std::isfinite(kf.timestamp)) return name + " has a non-finite timestamp";
  if (!finite(kf.T_c_w)) return name + " has a non-finite pose or a non-unit rotation";
  if (auto problem = check_features(f, info)) return name + ": " + *problem;
  if (kf.landmarks.size() != f.points.size() || kf.line_landmarks.size() != f.lines.size() ||
      kf.plane_landmarks.size() != f.planes.size())
    return name + " has " + std::to_string(kf.landmarks.size()) + "/" +
           std::to_string(kf.line_landmarks.size()) + "/" +
           std::to_string(kf.plane_landmarks.size()) + " point/line/plane landmark slots for " +
           std::to_string(f.points.size()) + "/" + std::to_string(f.lines.size()) + "/" +
           std::to_string(f.planes.size()) + " features";
  for (PointId p : kf.landmarks)
    if (p != kNoId && map.point(p) == nullptr)
      return name + " links point " + std::to_string(p) + ", not in the map";
  for (LineId l : kf.line_landmarks)
    if (l != kNoId && map.line(l) == nullptr)
      return name + " links line " + std::to_string(l) + ", not in the map";
  for (PlaneId p : kf.plane_landmarks)
    if (p != kNoId && map.plane(p) == nullptr)
      return name + " links plane " + std::to_string(p) + ", not in the map";
  for (const auto& [other, weight] : kf.covisibility)
    if (other == id || map.keyframe(other) == nullptr || weight <= 0)
      return name + " has a covisibility edge to " + kf_name(other) + " of weight " +
             std::to_string(weight);
  for (KeyFrameId other : kf.loop_edges) {
    const KeyFrame* o = map.keyframe(other);
    if (other == id || o == nullptr || o->loop_edges.count(id) == 0)
      return name + " has a loop edge to " + kf_name(other) + " that is not returned";
  }
  return std::nullopt;
}

/// One kind of landmark (`kind`: "point", "line", "plane"): each stored under its own id, its
/// numbers finite (`finite_numbers`), its observations within their keyframes' `count_of`
/// features. `next_free` becomes the largest id + 1.
template <typename Landmark, typename FiniteNumbers, typename CountOf>
std::optional<std::string> check_landmarks(const Map& map,
                                           const std::unordered_map<std::uint64_t, Landmark>& table,
                                           const std::string& kind, FiniteNumbers finite_numbers,
                                           CountOf count_of, std::uint64_t& next_free) {
  next_free = 0;
  for (const std::uint64_t id : sorted_ids(table)) {
    const Landmark& landmark = table.at(id);
    const std::string name = kind + " " + std::to_string(id);
    if (landmark.id != id) return name + " is stored under id " + std::to_string(landmark.id);
    if (id == kNoId) return "a " + kind + " has no id";
    next_free = std::max(next_free, id + 1);
    if (!finite_numbers(landmark)) return name + " has a non-finite number";
    if (auto problem = check_observations(map, name, landmark.observations, count_of))
      return problem;
  }
  return std::nullopt;
}

/// Everything load_session requires of a map beyond its file structure. A map that passes is
/// safe to use: every id a keyframe or landmark holds resolves, every index is in range.
std::optional<std::string> check_map(const Map& map, const SessionInfo& info) {
  KeyFrameId max_keyframe = 0;
  bool any_keyframe = false;
  for (const KeyFrameId id : sorted_ids(map.keyframes())) {
    if (auto problem = check_keyframe(map, id, info)) return problem;
    max_keyframe = std::max(max_keyframe, id);
    any_keyframe = true;
  }
  std::uint64_t max_point = 0, max_line = 0, max_plane = 0;
  if (auto problem = check_landmarks(
          map, map.points(), "point",
          [](const MapPoint& mp) {
            return mp.p_w.allFinite() && mp.normal.allFinite() && std::isfinite(mp.min_distance) &&
                   std::isfinite(mp.max_distance);
          },
          [](const KeyFrame& kf) { return kf.features->points.size(); }, max_point))
    return problem;
  if (auto problem = check_landmarks(
          map, map.lines(), "line",
          [](const MapLine& ml) { return ml.start_w.allFinite() && ml.end_w.allFinite(); },
          [](const KeyFrame& kf) { return kf.features->lines.size(); }, max_line))
    return problem;
  if (auto problem = check_landmarks(
          map, map.planes(), "plane",
          [](const MapPlane& mp) {
            return mp.normal.allFinite() && std::isfinite(mp.d) && finite(mp.hull);
          },
          [](const KeyFrame& kf) { return kf.features->planes.size(); }, max_plane))
    return problem;
  for (const KeyFrameId id : sorted_ids(map.erased_keyframes())) {
    const std::string name = "culled " + kf_name(id);
    if (id == kNoId) return "a culled keyframe has no id";
    if (map.keyframe(id) != nullptr) return name + " is also in the map";
    max_keyframe = std::max(max_keyframe, id);
    any_keyframe = true;
    if (!finite(map.erased_keyframes().at(id).T_this_parent))
      return name + " has a non-finite pose or a non-unit rotation";
  }
  // The next ids must be free, or the map would hand out an id in use.
  const Map::Counters counters = map.counters();
  if (any_keyframe && counters.next_keyframe <= max_keyframe)
    return "next keyframe id " + std::to_string(counters.next_keyframe) + " is in use";
  if (counters.next_point < max_point)
    return "next point id " + std::to_string(counters.next_point) + " is in use";
  if (counters.next_line < max_line)
    return "next line id " + std::to_string(counters.next_line) + " is in use";
  if (counters.next_plane < max_plane)
    return "next plane id " + std::to_string(counters.next_plane) + " is in use";
  return std::nullopt;
}

/// Saving only: every keyframe's pyramid is the one the info describes (load rebuilds it).
std::optional<std::string> check_pyramids(const Map& map, const SessionInfo& info) {
  const features::ScalePyramid expected(info.orb_levels, info.orb_scale_factor);
  for (const KeyFrameId id : sorted_ids(map.keyframes())) {
    const auto& pyramid = map.keyframes().at(id).features->pyramid;
    if (pyramid != nullptr && pyramid->scale != expected.scale)
      return kf_name(id) + " has an ORB pyramid of " + std::to_string(pyramid->levels()) +
             " levels that is not the session's (" + std::to_string(info.orb_levels) +
             " levels, scale factor " + std::to_string(info.orb_scale_factor) + ")";
  }
  return std::nullopt;
}

// --- reading ---

/// Reads the body [begin, end) of a file whose checksum was verified. Every read is bounds-checked
/// and every problem throws InputError "<path>: inconsistent session file: <context>: ...".
class Reader {
 public:
  Reader(const std::string& data, std::size_t begin, std::size_t end, const std::string& path)
      : data_(data), at_(begin), end_(end), path_(path) {}

  template <typename T>
  T get() {
    static_assert(std::is_arithmetic_v<T>);
    need(sizeof(T));
    T value;
    std::memcpy(&value, data_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return value;
  }
  /// An element count, refused when `count` elements of at least `min_bytes` each cannot fit in
  /// the bytes left.
  std::size_t count(std::size_t min_bytes, const char* what) {
    const auto n = get<std::uint64_t>();
    if (n > remaining() / min_bytes)
      fail(std::string(what) + " count " + std::to_string(n) + " does not fit in the " +
           std::to_string(remaining()) + " bytes left");
    return static_cast<std::size_t>(n);
  }
  Eigen::Vector2f vec2() {
    const float x = get<float>();
    return {x, get<float>()};
  }
  Eigen::Vector3d vec3() {
    const double x = get<double>();
    const double y = get<double>();
    return {x, y, get<double>()};
  }
  features::OrbDescriptor descriptor() {
    need(kDescriptorBytes);
    features::OrbDescriptor d;
    std::memcpy(d.bytes.data(), data_.data() + at_, kDescriptorBytes);
    at_ += kDescriptorBytes;
    return d;
  }
  SE3 pose() {
    const double w = get<double>();
    const double x = get<double>();
    const double y = get<double>();
    const double z = get<double>();
    // Kept as saved (checked to be unit afterwards): renormalising could change its last bits.
    return SE3::from_unit_quaternion(Eigen::Quaterniond(w, x, y, z), vec3());
  }
  /// keyframe -> int pairs in strictly increasing keyframe order.
  std::map<KeyFrameId, int> links(const char* what) {
    std::map<KeyFrameId, int> out;
    const std::size_t n = count(kLinkBytes, what);
    for (std::size_t i = 0; i < n; ++i) {
      const auto keyframe = get<std::uint64_t>();
      const auto value = get<std::int32_t>();
      if (!out.empty() && keyframe <= out.rbegin()->first)
        fail(std::string(what) + " are not in increasing keyframe order");
      out.emplace_hint(out.end(), keyframe, value);
    }
    return out;
  }
  std::vector<Eigen::Vector3d> hull() {
    std::vector<Eigen::Vector3d> out(count(kVector3Bytes, "hull point"));
    for (auto& p : out) p = vec3();
    return out;
  }
  std::vector<std::uint64_t> ids(const char* what) {
    std::vector<std::uint64_t> out(count(kU64, what));
    for (auto& id : out) id = get<std::uint64_t>();
    return out;
  }
  std::vector<std::uint8_t> flags(const char* what) {
    const std::size_t n = count(1, what);
    std::vector<std::uint8_t> out(data_.begin() + static_cast<std::ptrdiff_t>(at_),
                                  data_.begin() + static_cast<std::ptrdiff_t>(at_ + n));
    at_ += n;
    return out;
  }

  /// A rows x cols matrix of `type`, its bytes as Writer::matrix wrote them.
  cv::Mat matrix(int rows, int cols, int type) {
    const std::size_t n = static_cast<std::size_t>(rows) * cols * CV_ELEM_SIZE(type);
    need(n);  // before allocating: a count read from the file may be large
    cv::Mat m(rows, cols, type);
    std::memcpy(m.data, data_.data() + at_, n);
    at_ += n;
    return m;
  }

  std::size_t remaining() const { return end_ - at_; }
  /// Where the reader is, for messages ("keyframe 12").
  void set_context(std::string context) { context_ = std::move(context); }
  [[noreturn]] void fail(const std::string& problem) const {
    throw InputError(file_error(path_, "inconsistent session file: " +
                                           (context_.empty() ? "" : context_ + ": ") + problem));
  }

 private:
  void need(std::size_t bytes) const {
    if (bytes > remaining()) fail("the map ends early");
  }

  const std::string& data_;
  std::size_t at_;
  std::size_t end_;
  const std::string& path_;
  std::string context_;
};

SessionInfo read_info(Reader& r) {
  SessionInfo info;
  PinholeCamera& c = info.camera;
  c.fx = r.get<double>();
  c.fy = r.get<double>();
  c.cx = r.get<double>();
  c.cy = r.get<double>();
  c.width = r.get<std::int32_t>();
  c.height = r.get<std::int32_t>();
  for (double& d : c.distortion) d = r.get<double>();
  c.depth_factor = r.get<double>();
  c.bf = r.get<double>();
  c.readout_time = r.get<double>();
  info.vocabulary_id = r.get<std::uint64_t>();
  info.orb_levels = r.get<std::int32_t>();
  info.orb_scale_factor = r.get<double>();
  return info;
}

std::shared_ptr<const features::FrameFeatures> read_features(
    Reader& r, const SessionInfo& info,
    const std::shared_ptr<const features::ScalePyramid>& pyramid) {
  auto f = std::make_shared<features::FrameFeatures>();
  f->points.resize(r.count(kPointFeatureBytes, "point feature"));
  std::vector<features::Keypoint> keypoints;
  keypoints.reserve(f->points.size());
  for (auto& p : f->points) {
    p.keypoint.uv = r.vec2();
    p.keypoint.level = r.get<std::int32_t>();
    p.keypoint.angle_deg = r.get<float>();
    p.keypoint.response = r.get<float>();
    p.descriptor = r.descriptor();
    p.depth = r.get<float>();
    p.u_right = r.get<float>();
    p.plane = r.get<std::int32_t>();
    keypoints.push_back(p.keypoint);
  }
  f->lines.resize(r.count(kLineFeatureBytes, "line feature"));
  for (auto& l : f->lines) {
    l.start = r.vec2();
    l.end = r.vec2();
    l.descriptor = r.descriptor();
    const auto has_depth = r.get<std::uint8_t>();
    if (has_depth > 1) r.fail("a line feature's depth flag is " + std::to_string(has_depth));
    l.has_depth = has_depth == 1;
    l.start_c = r.vec3();
    l.end_c = r.vec3();
  }
  const std::size_t n_planes = r.count(kPlaneFeatureMinBytes, "plane feature");
  f->planes.reserve(n_planes);
  for (std::size_t i = 0; i < n_planes; ++i) {
    features::PlaneFeature p;
    p.normal = r.vec3();
    p.d = r.get<double>();
    p.centroid = r.vec3();
    p.num_pixels = r.get<std::int32_t>();
    p.rms = r.get<double>();
    p.hull = r.hull();
    f->planes.push_back(std::move(p));
  }
  // Rebuilt rather than stored, as the frame builder makes them (the camera size is checked).
  f->grid = features::KeypointGrid(keypoints, info.camera.width, info.camera.height);
  f->pyramid = pyramid;
  return f;
}

KeyFrame read_keyframe(Reader& r, const SessionInfo& info,
                       const std::shared_ptr<const features::ScalePyramid>& pyramid) {
  KeyFrame kf;
  kf.frame_id = r.get<std::uint64_t>();
  kf.timestamp = r.get<double>();
  kf.T_c_w = r.pose();
  kf.features = read_features(r, info, pyramid);
  kf.landmarks = r.ids("point landmark");
  kf.line_landmarks = r.ids("line landmark");
  kf.plane_landmarks = r.ids("plane landmark");
  kf.excluded_points = r.flags("excluded point");
  kf.excluded_lines = r.flags("excluded line");
  const std::map<KeyFrameId, int> covisible = r.links("covisibility edges");
  kf.covisibility.insert(covisible.begin(), covisible.end());
  for (KeyFrameId other : r.ids("loop edge")) kf.loop_edges.insert(other);
  return kf;
}

/// The id of the next element of a list written in increasing id order.
std::uint64_t read_id(Reader& r, std::optional<std::uint64_t>& previous, const char* what) {
  const auto id = r.get<std::uint64_t>();
  r.set_context(std::string(what) + " " + std::to_string(id));
  if (previous && id <= *previous)
    r.fail(std::string(what) + " ids are not in increasing order (duplicate or unsorted)");
  previous = id;
  return id;
}

/// One dense-map keyframe (write_dense_keyframe), checked as OccupancyMap::insert requires.
mapping::KeyframeSamples read_dense_keyframe(Reader& r, const SessionInfo& info) {
  mapping::KeyframeSamples kf;
  kf.id = r.get<std::uint64_t>();
  r.set_context("dense map keyframe " + std::to_string(kf.id));
  kf.T_w_c = r.pose();
  if (!finite(kf.T_w_c)) r.fail("a non-finite pose or a non-unit rotation");
  kf.camera = info.camera;
  kf.camera.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  kf.camera.fx = r.get<double>();
  kf.camera.fy = r.get<double>();
  kf.camera.cx = r.get<double>();
  kf.camera.cy = r.get<double>();
  kf.camera.width = r.get<std::int32_t>();
  kf.camera.height = r.get<std::int32_t>();
  if (auto problem = kf.camera.check()) r.fail("camera: " + *problem);
  if (kf.camera.width > kMaxImageSide || kf.camera.height > kMaxImageSide)
    r.fail("image size above " + std::to_string(kMaxImageSide));
  kf.step = r.get<std::int32_t>();
  const auto rows = r.get<std::int32_t>();
  const auto cols = r.get<std::int32_t>();
  if (kf.step < 1 || kf.step > 64 || rows != kf.camera.height / kf.step ||
      cols != kf.camera.width / kf.step || rows < 1 || cols < 1)
    r.fail("samples " + std::to_string(cols) + "x" + std::to_string(rows) + " at step " +
           std::to_string(kf.step) + " do not fit its " + std::to_string(kf.camera.width) + "x" +
           std::to_string(kf.camera.height) + " image");
  kf.depth_mm = r.matrix(rows, cols, CV_16UC1);
  kf.kind = r.matrix(rows, cols, CV_8UC1);
  double max_kind = 0.0;
  cv::minMaxLoc(kf.kind, nullptr, &max_kind);
  if (max_kind > mapping::KeyframeSamples::kMover)
    r.fail("a sample of kind " + std::to_string(static_cast<int>(max_kind)));
  const auto has_colour = r.get<std::uint8_t>();
  if (has_colour > 1) r.fail("its colour flag is " + std::to_string(has_colour));
  if (has_colour == 1) kf.colour = r.matrix(rows, cols, CV_8UC3);
  return kf;
}

/// The map's id counters and version.
Map::Counters read_counters(Reader& r) {
  Map::Counters counters;
  counters.next_keyframe = r.get<std::uint64_t>();
  counters.next_point = r.get<std::uint64_t>();
  counters.next_line = r.get<std::uint64_t>();
  counters.next_plane = r.get<std::uint64_t>();
  counters.last_keyframe = r.get<std::uint64_t>();
  counters.version = r.get<std::uint64_t>();
  return counters;
}

/// A map point (its id greater than `previous`, which it becomes).
MapPoint read_point(Reader& r, std::optional<std::uint64_t>& previous) {
  MapPoint mp;
  mp.id = read_id(r, previous, "point");
  mp.p_w = r.vec3();
  mp.descriptor = r.descriptor();
  mp.observations = r.links("observations");
  mp.normal = r.vec3();
  mp.min_distance = r.get<double>();
  mp.max_distance = r.get<double>();
  mp.first_keyframe = r.get<std::uint64_t>();
  for (auto& c : mp.color) c = r.get<std::uint8_t>();
  mp.visible = r.get<std::int32_t>();
  mp.found = r.get<std::int32_t>();
  return mp;
}

/// A map line (its id greater than `previous`, which it becomes).
MapLine read_line(Reader& r, std::optional<std::uint64_t>& previous) {
  MapLine ml;
  ml.id = read_id(r, previous, "line");
  ml.start_w = r.vec3();
  ml.end_w = r.vec3();
  ml.descriptor = r.descriptor();
  ml.observations = r.links("observations");
  ml.first_keyframe = r.get<std::uint64_t>();
  ml.visible = r.get<std::int32_t>();
  ml.found = r.get<std::int32_t>();
  return ml;
}

/// A map plane (its id greater than `previous`, which it becomes).
MapPlane read_plane(Reader& r, std::optional<std::uint64_t>& previous) {
  MapPlane mp;
  mp.id = read_id(r, previous, "plane");
  mp.normal = r.vec3();
  mp.d = r.get<double>();
  mp.observations = r.links("observations");
  mp.hull = r.hull();
  mp.first_keyframe = r.get<std::uint64_t>();
  return mp;
}

Session read_body(Reader& r) {
  Session session;
  r.set_context("session info");
  session.info = read_info(r);
  if (auto problem = check_info(session.info)) r.fail(*problem);
  const SessionInfo& info = session.info;
  const auto pyramid =
      std::make_shared<const features::ScalePyramid>(info.orb_levels, info.orb_scale_factor);
  session.map = std::make_unique<Map>();
  Map& map = *session.map;

  r.set_context("map counters");
  map.restore_counters(read_counters(r));

  r.set_context("");
  std::optional<std::uint64_t> previous;
  const std::size_t n_keyframes = r.count(kKeyFrameMinBytes, "keyframe");
  for (std::size_t i = 0; i < n_keyframes; ++i) {
    const KeyFrameId id = read_id(r, previous, "keyframe");
    KeyFrame kf = read_keyframe(r, info, pyramid);
    kf.id = id;
    map.restore_keyframe(std::move(kf));
  }

  r.set_context("");
  previous.reset();
  const std::size_t n_points = r.count(kMapPointMinBytes, "point");
  for (std::size_t i = 0; i < n_points; ++i) map.restore_point(read_point(r, previous));

  r.set_context("");
  previous.reset();
  const std::size_t n_lines = r.count(kMapLineMinBytes, "line");
  for (std::size_t i = 0; i < n_lines; ++i) map.restore_line(read_line(r, previous));

  r.set_context("");
  previous.reset();
  const std::size_t n_planes = r.count(kMapPlaneMinBytes, "plane");
  for (std::size_t i = 0; i < n_planes; ++i) map.restore_plane(read_plane(r, previous));

  r.set_context("");
  previous.reset();
  const std::size_t n_erased = r.count(kErasedBytes, "culled keyframe");
  for (std::size_t i = 0; i < n_erased; ++i) {
    const KeyFrameId id = read_id(r, previous, "culled keyframe");
    ErasedKeyFrame erased;
    erased.parent = r.get<std::uint64_t>();
    erased.T_this_parent = r.pose();
    map.restore_erased_keyframe(id, erased);
  }

  r.set_context("");
  const std::size_t n_dense = r.count(kDenseMinBytes, "dense map keyframe");
  session.dense.reserve(n_dense);
  for (std::size_t i = 0; i < n_dense; ++i) {
    session.dense.push_back(read_dense_keyframe(r, session.info));
    if (i > 0 && session.dense[i].id <= session.dense[i - 1].id)
      r.fail("dense map keyframes are not in increasing id order");
  }

  r.set_context("");
  if (r.remaining() != 0) r.fail(std::to_string(r.remaining()) + " unexpected bytes after the map");
  if (auto problem = check_map(map, info)) r.fail(*problem);
  return session;
}

/// What read_dense_keyframe requires of the dense map's keyframes (ids increasing, samples
/// that fit their camera), so that a file that is written always loads.
std::optional<std::string> check_dense(const std::vector<mapping::KeyframeSamples>& dense) {
  for (std::size_t i = 0; i < dense.size(); ++i) {
    const mapping::KeyframeSamples& kf = dense[i];
    const std::string name = "dense map keyframe " + std::to_string(kf.id);
    if (i > 0 && kf.id <= dense[i - 1].id) return name + ": ids not in increasing order";
    if (!finite(kf.T_w_c)) return name + " has a non-finite pose or a non-unit rotation";
    if (auto problem = kf.check()) return name + ": " + *problem;
    if (kf.depth_mm.empty()) return name + ": no samples (a camera narrower than its step)";
  }
  return std::nullopt;
}

}  // namespace

void save_session(const std::string& path, const Map& map, const SessionInfo& info,
                  const std::vector<mapping::KeyframeSamples>& dense) {
  auto problem = check_info(info);
  if (!problem) problem = check_map(map, info);
  if (!problem) problem = check_pyramids(map, info);
  if (!problem) problem = check_dense(dense);
  if (problem) throw InputError(file_error(path, "cannot save the map: " + *problem));

  Writer w;
  w.bytes().append(kMagic, sizeof(kMagic));
  w.put<std::uint32_t>(kFormatVersion);
  write_info(w, info);
  const Map::Counters counters = map.counters();
  w.put<std::uint64_t>(counters.next_keyframe);
  w.put<std::uint64_t>(counters.next_point);
  w.put<std::uint64_t>(counters.next_line);
  w.put<std::uint64_t>(counters.next_plane);
  w.put<std::uint64_t>(counters.last_keyframe);
  w.put<std::uint64_t>(counters.version);

  const auto keyframe_ids = sorted_ids(map.keyframes());
  w.count(keyframe_ids.size());
  for (const KeyFrameId id : keyframe_ids) write_keyframe(w, map.keyframes().at(id));

  const auto point_ids = sorted_ids(map.points());
  w.count(point_ids.size());
  for (const PointId id : point_ids) {
    const MapPoint& mp = map.points().at(id);
    w.put<std::uint64_t>(mp.id);
    w.vec3(mp.p_w);
    w.descriptor(mp.descriptor);
    w.links(mp.observations);
    w.vec3(mp.normal);
    w.put<double>(mp.min_distance);
    w.put<double>(mp.max_distance);
    w.put<std::uint64_t>(mp.first_keyframe);
    for (const std::uint8_t c : mp.color) w.put<std::uint8_t>(c);
    w.put<std::int32_t>(mp.visible);
    w.put<std::int32_t>(mp.found);
  }

  const auto line_ids = sorted_ids(map.lines());
  w.count(line_ids.size());
  for (const LineId id : line_ids) {
    const MapLine& ml = map.lines().at(id);
    w.put<std::uint64_t>(ml.id);
    w.vec3(ml.start_w);
    w.vec3(ml.end_w);
    w.descriptor(ml.descriptor);
    w.links(ml.observations);
    w.put<std::uint64_t>(ml.first_keyframe);
    w.put<std::int32_t>(ml.visible);
    w.put<std::int32_t>(ml.found);
  }

  const auto plane_ids = sorted_ids(map.planes());
  w.count(plane_ids.size());
  for (const PlaneId id : plane_ids) {
    const MapPlane& mp = map.planes().at(id);
    w.put<std::uint64_t>(mp.id);
    w.vec3(mp.normal);
    w.put<double>(mp.d);
    w.links(mp.observations);
    w.hull(mp.hull);
    w.put<std::uint64_t>(mp.first_keyframe);
  }

  const auto erased_ids = sorted_ids(map.erased_keyframes());
  w.count(erased_ids.size());
  for (const KeyFrameId id : erased_ids) {
    const ErasedKeyFrame& erased = map.erased_keyframes().at(id);
    w.put<std::uint64_t>(id);
    w.put<std::uint64_t>(erased.parent);
    w.pose(erased.T_this_parent);
  }

  w.count(dense.size());
  for (const mapping::KeyframeSamples& kf : dense) write_dense_keyframe(w, kf);

  w.put<std::uint64_t>(place::file_checksum(w.bytes()));
  io::write_file_atomic(path, w.bytes());
}

Session load_session(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw InputError(file_error(path, "is a directory, not a session file"));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file_error(path, "cannot open the session file"));
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(file_error(path, "cannot read the session file"));
  if (data.empty()) throw InputError(file_error(path, "empty file, not an mcslam session"));
  const std::size_t magic_bytes = std::min(data.size(), sizeof(kMagic));
  if (std::memcmp(data.data(), kMagic, magic_bytes) != 0)
    throw InputError(file_error(path, "not an mcslam session (bad magic)"));
  if (data.size() < kHeaderBytes + kChecksumBytes)
    throw InputError(
        file_error(path, "truncated session file (" + std::to_string(data.size()) + " bytes)"));
  std::uint32_t version = 0;
  std::memcpy(&version, data.data() + sizeof(kMagic), sizeof(version));
  if (version == 2)
    throw InputError(
        file_error(path,
                   "session format version 2, from before sessions kept the dense map; this build "
                   "reads version " +
                       std::to_string(kFormatVersion) +
                       ": run the sequence again with --save-session to make a session of this "
                       "format"));
  if (version != kFormatVersion)
    throw InputError(file_error(path, "session format version " + std::to_string(version) +
                                          ", this build reads version " +
                                          std::to_string(kFormatVersion)));
  const std::size_t body_end = data.size() - kChecksumBytes;
  std::uint64_t stored = 0;
  std::memcpy(&stored, data.data() + body_end, sizeof(stored));
  if (stored != place::file_checksum(std::string_view(data.data(), body_end)))
    throw InputError(file_error(path, "corrupt or truncated session file (checksum mismatch)"));
  Reader reader(data, kHeaderBytes, body_end, path);
  return read_body(reader);
}

}  // namespace mcslam::map
