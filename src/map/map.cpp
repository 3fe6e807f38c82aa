#include "mcslam/map/map.hpp"

#include <algorithm>

namespace mcslam::map {

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

std::vector<KeyFrameId> Map::best_covisible(KeyFrameId id, std::size_t n, int min_weight) const {
  const KeyFrame* kf = keyframe(id);
  if (kf == nullptr) return {};
  std::vector<std::pair<int, KeyFrameId>> ranked;
  for (const auto& [other, weight] : kf->covisibility)
    if (weight >= min_weight) ranked.emplace_back(weight, other);
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  std::vector<KeyFrameId> out;
  for (std::size_t i = 0; i < ranked.size() && i < n; ++i) out.push_back(ranked[i].second);
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
  for (const auto& [other, weight] : kit->second.covisibility)
    if (auto it = keyframes_.find(other); it != keyframes_.end()) it->second.covisibility.erase(id);
  // Frames referenced to keyframes whose parent was this one keep resolving through the chain.
  erased_keyframes_[id] = erased;
  keyframes_.erase(kit);
  ++version_;
}

void Map::set_keyframe_pose(KeyFrameId id, const SE3& T_c_w) {
  if (auto it = keyframes_.find(id); it != keyframes_.end()) it->second.T_c_w = T_c_w;
}

void Map::set_point_position(PointId id, const Eigen::Vector3d& p_w) {
  if (auto it = points_.find(id); it != points_.end()) it->second.p_w = p_w;
}

void Map::update_point_appearance(PointId id) {
  auto pit = points_.find(id);
  if (pit == points_.end()) return;
  MapPoint& mp = pit->second;
  std::vector<const features::PointFeature*> observed;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  KeyFrameId ref = kNoId;
  for (const auto& [kf_id, index] : mp.observations) {
    const KeyFrame* kf = keyframe(kf_id);
    if (kf == nullptr) continue;
    observed.push_back(&kf->features->points[static_cast<std::size_t>(index)]);
    normal += (mp.p_w - kf->camera_center()).normalized();
    if (ref == kNoId) ref = kf_id;
  }
  if (observed.empty()) return;
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
  // Representative descriptor: least median Hamming distance to the other observations.
  if (observed.size() <= 2) {
    mp.descriptor = observed.front()->descriptor;
    return;
  }
  const std::size_t n = observed.size();
  int best_median = std::numeric_limits<int>::max();
  std::vector<int> distances(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j)
      distances[j] = features::hamming_distance(observed[i]->descriptor, observed[j]->descriptor);
    std::nth_element(distances.begin(), distances.begin() + static_cast<long>((n - 1) / 2),
                     distances.end());
    const int median = distances[(n - 1) / 2];
    if (median < best_median) {
      best_median = median;
      mp.descriptor = observed[i]->descriptor;
    }
  }
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

}  // namespace mcslam::map
