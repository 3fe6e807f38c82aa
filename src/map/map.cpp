#include "mcslam/map/map.hpp"

#include <algorithm>
#include <cmath>

namespace mcslam::map {
namespace {

/// The descriptor with the least median Hamming distance to the others (ORB-SLAM2's choice of a
/// landmark's representative descriptor); the first one when there are at most two.
features::OrbDescriptor representative_descriptor(
    const std::vector<const features::OrbDescriptor*>& observed) {
  const std::size_t n = observed.size();
  if (n <= 2) return *observed.front();
  features::OrbDescriptor best;
  int best_median = std::numeric_limits<int>::max();
  std::vector<int> distances(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j)
      distances[j] = features::hamming_distance(*observed[i], *observed[j]);
    std::nth_element(distances.begin(), distances.begin() + static_cast<long>((n - 1) / 2),
                     distances.end());
    if (distances[(n - 1) / 2] < best_median) {
      best_median = distances[(n - 1) / 2];
      best = *observed[i];
    }
  }
  return best;
}

}  // namespace

int KeyFrame::num_landmarks() const {
  return static_cast<int>(
      std::count_if(landmarks.begin(), landmarks.end(), [](PointId p) { return p != kNoId; }));
}

const KeyFrame* Map::keyframe(KeyFrameId id) const {
  const auto it = keyframes_.find(id);
  return it == keyframes_.end() ? nullptr : &it->second;
}

const MapPoint* Map::point(PointId id) const {
  const auto it = points_.find(id);
  return it == points_.end() ? nullptr : &it->second;
}

const MapLine* Map::line(LineId id) const {
  const auto it = lines_.find(id);
  return it == lines_.end() ? nullptr : &it->second;
}

const MapPlane* Map::plane(PlaneId id) const {
  const auto it = planes_.find(id);
  return it == planes_.end() ? nullptr : &it->second;
}

std::vector<KeyFrameId> Map::best_covisible(KeyFrameId id, std::size_t n, int min_weight) const {
  const KeyFrame* kf = keyframe(id);
  if (kf == nullptr) return {};
  std::vector<std::pair<int, KeyFrameId>> ranked;
  for (const auto& [other, weight] : kf->covisibility)
    if (weight >= min_weight) ranked.emplace_back(weight, other);
  // Only the first n are needed, in order (weight, then id: a total order, so the result does
  // not depend on the hash map's order).
  const auto first_n = ranked.begin() + static_cast<std::ptrdiff_t>(std::min(n, ranked.size()));
  std::partial_sort(ranked.begin(), first_n, ranked.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  std::vector<KeyFrameId> out;
  for (auto it = ranked.begin(); it != first_n; ++it) out.push_back(it->second);
  return out;
}

std::optional<SE3> Map::keyframe_pose_T_c_w(KeyFrameId id) const {
  SE3 T_id_current;  // accumulates T_id_k along the chain
  KeyFrameId current = id;
  for (std::size_t hops = 0; hops <= erased_keyframes_.size() + 1; ++hops) {
    if (const KeyFrame* kf = keyframe(current)) return T_id_current * kf->T_c_w;
    const auto it = erased_keyframes_.find(current);
    if (it == erased_keyframes_.end()) return std::nullopt;
    T_id_current = T_id_current * it->second.T_this_parent;
    current = it->second.parent;
  }
  return std::nullopt;
}

KeyFrameId Map::add_keyframe(KeyFrame keyframe) {
  if (keyframe.id == kNoId || keyframes_.count(keyframe.id) != 0 ||
      erased_keyframes_.count(keyframe.id) != 0)
    keyframe.id = next_keyframe_id_;
  const KeyFrameId id = keyframe.id;
  next_keyframe_id_ = std::max(next_keyframe_id_, id + 1);
  keyframe.landmarks.assign(keyframe.features->points.size(), kNoId);
  keyframe.line_landmarks.assign(keyframe.features->lines.size(), kNoId);
  keyframe.plane_landmarks.assign(keyframe.features->planes.size(), kNoId);
  if (database_ && keyframe.bow) database_->add(id, keyframe.bow->bow);
  keyframes_.emplace(id, std::move(keyframe));
  last_keyframe_ = id;
  ++version_;
  return id;
}

PointId Map::add_point(const Eigen::Vector3d& p_w, KeyFrameId keyframe, int feature_index) {
  const PointId id = next_point_id_++;
  MapPoint mp;
  mp.id = id;
  mp.p_w = p_w;
  mp.first_keyframe = keyframe;
  points_.emplace(id, std::move(mp));
  add_observation(id, keyframe, feature_index);
  update_point_appearance(id);
  return id;
}

void Map::add_observation(PointId point, KeyFrameId keyframe, int feature_index) {
  auto pit = points_.find(point);
  auto kit = keyframes_.find(keyframe);
  if (pit == points_.end() || kit == keyframes_.end()) return;
  auto& slot = kit->second.landmarks.at(static_cast<std::size_t>(feature_index));
  if (slot != kNoId) return;
  if (pit->second.observations.count(keyframe) != 0) return;  // one feature per keyframe
  slot = point;
  pit->second.observations.emplace(keyframe, feature_index);
}

void Map::erase_observation(PointId point, KeyFrameId keyframe) {
  auto pit = points_.find(point);
  if (pit == points_.end()) return;
  const auto oit = pit->second.observations.find(keyframe);
  if (oit == pit->second.observations.end()) return;
  if (auto kit = keyframes_.find(keyframe); kit != keyframes_.end())
    kit->second.landmarks[static_cast<std::size_t>(oit->second)] = kNoId;
  pit->second.observations.erase(oit);
  if (pit->second.observations.empty()) {
    points_.erase(pit);
  } else {
    update_point_appearance(point);
  }
}

void Map::erase_point(PointId point) {
  auto pit = points_.find(point);
  if (pit == points_.end()) return;
  for (const auto& [kf_id, index] : pit->second.observations)
    if (auto kit = keyframes_.find(kf_id); kit != keyframes_.end())
      kit->second.landmarks[static_cast<std::size_t>(index)] = kNoId;
  points_.erase(pit);
}

void Map::replace_point(PointId old_point, PointId new_point) {
  if (old_point == new_point) return;
  auto oit = points_.find(old_point);
  auto nit = points_.find(new_point);
  if (oit == points_.end() || nit == points_.end()) return;
  const auto observations = oit->second.observations;
  const int visible = oit->second.visible;
  const int found = oit->second.found;
  erase_point(old_point);
  replaced_points_[old_point] = new_point;
  for (const auto& [kf_id, index] : observations) add_observation(new_point, kf_id, index);
  nit = points_.find(new_point);
  nit->second.visible += visible;
  nit->second.found += found;
  update_point_appearance(new_point);
}

void Map::erase_keyframe(KeyFrameId id) {
  auto kit = keyframes_.find(id);
  if (kit == keyframes_.end()) return;
  // Remember the pose relative to the best remaining covisible keyframe.
  const auto best = best_covisible(id, 1);
  ErasedKeyFrame erased;
  if (!best.empty()) {
    erased.parent = best.front();
    erased.T_this_parent = kit->second.T_c_w * keyframes_.at(best.front()).T_c_w.inverse();
  }
  const std::vector<PointId> landmarks = kit->second.landmarks;
  for (PointId p : landmarks)
    if (p != kNoId) erase_observation(p, id);
  const std::vector<LineId> lines = kit->second.line_landmarks;
  for (LineId l : lines)
    if (l != kNoId) erase_line_observation(l, id);
  const std::vector<PlaneId> planes = kit->second.plane_landmarks;
  for (PlaneId p : planes)
    if (p != kNoId) erase_plane_observation(p, id);
  for (const auto& [other, weight] : kit->second.covisibility)
    if (auto it = keyframes_.find(other); it != keyframes_.end()) it->second.covisibility.erase(id);
  for (KeyFrameId other : kit->second.loop_edges)
    if (auto it = keyframes_.find(other); it != keyframes_.end()) it->second.loop_edges.erase(id);
  if (database_) database_->erase(id);
  // Frames referenced to keyframes whose parent was this one keep resolving through the chain.
  erased_keyframes_[id] = erased;
  keyframes_.erase(kit);
  ++version_;
}

void Map::set_plane_hull(PlaneId id, std::vector<Eigen::Vector3d> hull_w) {
  if (auto it = planes_.find(id); it != planes_.end()) it->second.hull = std::move(hull_w);
}

void Map::enable_database(int words) {
  database_.emplace(words);
  for (const auto& [id, kf] : keyframes_)
    if (kf.bow) database_->add(id, kf.bow->bow);
}

void Map::set_keyframe_bow(KeyFrameId id, std::shared_ptr<const place::BowImage> bow) {
  auto it = keyframes_.find(id);
  if (it == keyframes_.end()) return;
  it->second.bow = std::move(bow);
  if (database_) {
    if (it->second.bow)
      database_->add(id, it->second.bow->bow);
    else
      database_->erase(id);
  }
}

void Map::add_loop_edge(KeyFrameId a, KeyFrameId b) {
  auto ia = keyframes_.find(a);
  auto ib = keyframes_.find(b);
  if (ia == keyframes_.end() || ib == keyframes_.end() || a == b) return;
  ia->second.loop_edges.insert(b);
  ib->second.loop_edges.insert(a);
  ++version_;
}

void Map::set_keyframe_pose(KeyFrameId id, const SE3& T_c_w) {
  if (auto it = keyframes_.find(id); it != keyframes_.end()) it->second.T_c_w = T_c_w;
}

void Map::set_point_position(PointId id, const Eigen::Vector3d& p_w) {
  if (auto it = points_.find(id); it != points_.end()) it->second.p_w = p_w;
}

void Map::set_point_color(PointId id, const std::array<std::uint8_t, 3>& rgb) {
  if (auto it = points_.find(id); it != points_.end()) it->second.color = rgb;
}

namespace {

/// Follows the forward links of fused landmarks from `id` to one that exists (see
/// Map::resolve_point). Chains are short (a landmark is fused a few times at most); the bound
/// guards against a cycle.
template <typename Id, typename Landmarks>
Id follow_replacements(Id id, const Landmarks& landmarks, const std::unordered_map<Id, Id>& links) {
  for (std::size_t step = 0; step <= links.size() && id != kNoId; ++step) {
    if (landmarks.count(id) != 0) return id;
    const auto it = links.find(id);
    if (it == links.end()) return kNoId;
    id = it->second;
  }
  return kNoId;
}

}  // namespace

PointId Map::resolve_point(PointId id) const {
  return follow_replacements(id, points_, replaced_points_);
}

LineId Map::resolve_line(LineId id) const {
  return follow_replacements(id, lines_, replaced_lines_);
}

void Map::update_point_appearance(PointId id) {
  update_point_geometry(id);
  auto pit = points_.find(id);
  if (pit == points_.end()) return;
  MapPoint& mp = pit->second;
  std::vector<const features::OrbDescriptor*> descriptors;
  for (const auto& [kf_id, index] : mp.observations)
    if (const KeyFrame* kf = keyframe(kf_id))
      descriptors.push_back(&kf->features->points[static_cast<std::size_t>(index)].descriptor);
  if (!descriptors.empty()) mp.descriptor = representative_descriptor(descriptors);
}

void Map::update_point_geometry(PointId id) {
  auto pit = points_.find(id);
  if (pit == points_.end()) return;
  MapPoint& mp = pit->second;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  KeyFrameId ref = kNoId;
  for (const auto& [kf_id, index] : mp.observations) {
    const KeyFrame* kf = keyframe(kf_id);
    if (kf == nullptr) continue;
    normal += (mp.p_w - kf->camera_center()).normalized();
    if (ref == kNoId) ref = kf_id;
  }
  if (ref == kNoId) return;
  mp.normal = normal.normalized();
  // Distance range from the reference (first) observation, as in ORB-SLAM2.
  const KeyFrame* ref_kf = keyframe(ref);
  const auto& ref_feature =
      ref_kf->features->points[static_cast<std::size_t>(mp.observations.at(ref))];
  const auto& pyramid = *ref_kf->features->pyramid;
  const double dist = (mp.p_w - ref_kf->camera_center()).norm();
  const int level = ref_feature.keypoint.level;
  mp.max_distance = dist * pyramid.scale[static_cast<std::size_t>(level)];
  mp.min_distance = mp.max_distance / pyramid.scale.back();
}

void Map::update_covisibility(KeyFrameId id) {
  auto kit = keyframes_.find(id);
  if (kit == keyframes_.end()) return;
  std::unordered_map<KeyFrameId, int> counts;
  for (PointId p : kit->second.landmarks) {
    if (p == kNoId) continue;
    const MapPoint* mp = point(p);
    if (mp == nullptr) continue;
    for (const auto& obs : mp->observations)
      if (obs.first != id) ++counts[obs.first];
  }
  // Shared lines count like shared points: in low-texture scenes they hold keyframes together.
  for (LineId l : kit->second.line_landmarks) {
    if (l == kNoId) continue;
    const MapLine* ml = line(l);
    if (ml == nullptr) continue;
    for (const auto& obs : ml->observations)
      if (obs.first != id) ++counts[obs.first];
  }
  for (const auto& [other, weight] : kit->second.covisibility)
    if (auto it = keyframes_.find(other); it != keyframes_.end()) it->second.covisibility.erase(id);
  kit->second.covisibility = counts;
  for (const auto& [other, weight] : counts)
    if (auto it = keyframes_.find(other); it != keyframes_.end())
      it->second.covisibility[id] = weight;
}

void Map::add_tracking_statistics(PointId id, int visible, int found) {
  if (auto it = points_.find(id); it != points_.end()) {
    it->second.visible += visible;
    it->second.found += found;
  }
}

// --- lines ---

LineId Map::add_line(const Eigen::Vector3d& start_w, const Eigen::Vector3d& end_w,
                     KeyFrameId keyframe, int segment_index) {
  const LineId id = next_line_id_++;
  MapLine ml;
  ml.id = id;
  ml.start_w = start_w;
  ml.end_w = end_w;
  ml.first_keyframe = keyframe;
  lines_.emplace(id, std::move(ml));
  add_line_observation(id, keyframe, segment_index);
  update_line_appearance(id);
  return id;
}

void Map::add_line_observation(LineId line_id, KeyFrameId keyframe, int segment_index) {
  auto lit = lines_.find(line_id);
  auto kit = keyframes_.find(keyframe);
  if (lit == lines_.end() || kit == keyframes_.end()) return;
  auto& slot = kit->second.line_landmarks.at(static_cast<std::size_t>(segment_index));
  if (slot != kNoId || lit->second.observations.count(keyframe) != 0) return;
  slot = line_id;
  lit->second.observations.emplace(keyframe, segment_index);
}

void Map::erase_line_observation(LineId line_id, KeyFrameId keyframe) {
  auto lit = lines_.find(line_id);
  if (lit == lines_.end()) return;
  const auto oit = lit->second.observations.find(keyframe);
  if (oit == lit->second.observations.end()) return;
  if (auto kit = keyframes_.find(keyframe); kit != keyframes_.end())
    kit->second.line_landmarks[static_cast<std::size_t>(oit->second)] = kNoId;
  lit->second.observations.erase(oit);
  if (lit->second.observations.empty())
    lines_.erase(lit);
  else
    update_line_appearance(line_id);
}

void Map::erase_line(LineId line_id) {
  auto lit = lines_.find(line_id);
  if (lit == lines_.end()) return;
  for (const auto& [kf_id, index] : lit->second.observations)
    if (auto kit = keyframes_.find(kf_id); kit != keyframes_.end())
      kit->second.line_landmarks[static_cast<std::size_t>(index)] = kNoId;
  lines_.erase(lit);
}

void Map::replace_line(LineId old_line, LineId new_line) {
  if (old_line == new_line) return;
  auto oit = lines_.find(old_line);
  if (oit == lines_.end() || lines_.count(new_line) == 0) return;
  const MapLine old = oit->second;
  erase_line(old_line);
  replaced_lines_[old_line] = new_line;
  for (const auto& [kf_id, index] : old.observations) add_line_observation(new_line, kf_id, index);
  MapLine& target = lines_.at(new_line);
  target.visible += old.visible;
  target.found += old.found;
  extend_line(new_line, old.start_w, old.end_w);
  update_line_appearance(new_line);
}

void Map::set_line_endpoints(LineId id, const Eigen::Vector3d& start_w,
                             const Eigen::Vector3d& end_w) {
  if (auto it = lines_.find(id); it != lines_.end()) {
    it->second.start_w = start_w;
    it->second.end_w = end_w;
  }
}

void Map::extend_line(LineId id, const Eigen::Vector3d& start_w, const Eigen::Vector3d& end_w) {
  auto it = lines_.find(id);
  if (it == lines_.end()) return;
  MapLine& ml = it->second;
  const double length = ml.length();
  if (!(length > 1e-9)) return;
  const Eigen::Vector3d dir = (ml.end_w - ml.start_w) / length;
  // Positions along the line, the current segment being [0, length].
  const double a = dir.dot(start_w - ml.start_w);
  const double b = dir.dot(end_w - ml.start_w);
  const double lo = std::min({0.0, a, b});
  const double hi = std::max({length, a, b});
  const Eigen::Vector3d origin = ml.start_w;
  ml.start_w = origin + lo * dir;
  ml.end_w = origin + hi * dir;
}

void Map::update_line_appearance(LineId id) {
  auto it = lines_.find(id);
  if (it == lines_.end()) return;
  std::vector<const features::LineDescriptor*> observed;
  for (const auto& [kf_id, index] : it->second.observations)
    if (const KeyFrame* kf = keyframe(kf_id))
      observed.push_back(&kf->features->lines[static_cast<std::size_t>(index)].descriptor);
  if (!observed.empty()) it->second.descriptor = representative_descriptor(observed);
}

void Map::add_line_statistics(LineId id, int visible, int found) {
  if (auto it = lines_.find(id); it != lines_.end()) {
    it->second.visible += visible;
    it->second.found += found;
  }
}

// --- planes ---

PlaneId Map::add_plane(const Eigen::Vector4d& plane_w, const std::vector<Eigen::Vector3d>& hull_w,
                       KeyFrameId keyframe, int plane_index) {
  const PlaneId id = next_plane_id_++;
  MapPlane mp;
  mp.id = id;
  const double norm = plane_w.head<3>().norm();
  mp.normal = plane_w.head<3>() / norm;
  mp.d = plane_w[3] / norm;
  mp.first_keyframe = keyframe;
  mp.hull = features::plane_hull(mp.normal, mp.d, hull_w);
  planes_.emplace(id, std::move(mp));
  add_plane_observation(id, keyframe, plane_index);
  return id;
}

void Map::add_plane_observation(PlaneId plane_id, KeyFrameId keyframe, int plane_index) {
  auto pit = planes_.find(plane_id);
  auto kit = keyframes_.find(keyframe);
  if (pit == planes_.end() || kit == keyframes_.end()) return;
  auto& slot = kit->second.plane_landmarks.at(static_cast<std::size_t>(plane_index));
  if (slot != kNoId || pit->second.observations.count(keyframe) != 0) return;
  slot = plane_id;
  pit->second.observations.emplace(keyframe, plane_index);
}

void Map::erase_plane_observation(PlaneId plane_id, KeyFrameId keyframe) {
  auto pit = planes_.find(plane_id);
  if (pit == planes_.end()) return;
  const auto oit = pit->second.observations.find(keyframe);
  if (oit == pit->second.observations.end()) return;
  if (auto kit = keyframes_.find(keyframe); kit != keyframes_.end())
    kit->second.plane_landmarks[static_cast<std::size_t>(oit->second)] = kNoId;
  pit->second.observations.erase(oit);
  if (pit->second.observations.empty()) planes_.erase(pit);
}

void Map::set_plane(PlaneId id, const Eigen::Vector4d& plane_w) {
  auto it = planes_.find(id);
  if (it == planes_.end()) return;
  const double norm = plane_w.head<3>().norm();
  if (!(norm > 0.0)) return;
  it->second.normal = plane_w.head<3>() / norm;
  it->second.d = plane_w[3] / norm;
  // Keep the extent on the moved plane.
  it->second.hull = features::plane_hull(it->second.normal, it->second.d, it->second.hull);
}

void Map::extend_plane(PlaneId id, const std::vector<Eigen::Vector3d>& points_w) {
  auto it = planes_.find(id);
  if (it == planes_.end()) return;
  std::vector<Eigen::Vector3d> all = it->second.hull;
  all.insert(all.end(), points_w.begin(), points_w.end());
  it->second.hull = features::plane_hull(it->second.normal, it->second.d, all);
}

void Map::replace_plane(PlaneId old_plane, PlaneId new_plane) {
  if (old_plane == new_plane) return;
  auto oit = planes_.find(old_plane);
  if (oit == planes_.end() || planes_.count(new_plane) == 0) return;
  const MapPlane old = oit->second;
  for (const auto& [kf_id, index] : old.observations)
    if (auto kit = keyframes_.find(kf_id); kit != keyframes_.end())
      kit->second.plane_landmarks[static_cast<std::size_t>(index)] = kNoId;
  planes_.erase(oit);
  for (const auto& [kf_id, index] : old.observations)
    add_plane_observation(new_plane, kf_id, index);
  extend_plane(new_plane, old.hull);
}

}  // namespace mcslam::map
