#include "mcslam/slam/loop_closer.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <unordered_map>
#include <unordered_set>

#include "map_adjustment.hpp"
#include "mcslam/core/thread_priority.hpp"
#include "mcslam/core/worker.hpp"
#include "mcslam/optim/pose_optimizer.hpp"
#include "mcslam/place/matching.hpp"
#include "mcslam/slam/local_mapper.hpp"
#include "measurement.hpp"

namespace mcslam::slam {
namespace {

/// A point seen from `T_c_w` against a keypoint with depth: u, v and the virtual right
/// coordinate within the chi-square 95 % bound of 3 degrees of freedom at the keypoint's level.
bool consistent(const PinholeCamera& camera, const features::PointFeature& f,
                const features::ScalePyramid& pyramid, const SE3& T_c_w,
                const Eigen::Vector3d& p_w) {
  const Eigen::Vector3d p_c = T_c_w * p_w;
  if (p_c.z() <= 0.0) return false;
  const Eigen::Vector2d uv = camera.project(p_c);
  const double ur = camera.right_u(uv.x(), p_c.z());
  const double e2 =
      (f.keypoint.uv.cast<double>() - uv).squaredNorm() + (f.u_right - ur) * (f.u_right - ur);
  return e2 * pyramid.inv_sigma2[static_cast<std::size_t>(f.keypoint.level)] < 7.815;
}

/// The rigid transform taking `from` onto `to` (least squares, no scale).
SE3 align(const std::vector<Eigen::Vector3d>& from, const std::vector<Eigen::Vector3d>& to) {
  Eigen::Matrix3Xd a(3, from.size()), b(3, to.size());
  for (std::size_t k = 0; k < from.size(); ++k) {
    a.col(static_cast<Eigen::Index>(k)) = from[k];
    b.col(static_cast<Eigen::Index>(k)) = to[k];
  }
  const Eigen::Matrix4d T = Eigen::umeyama(a, b, false);
  return SE3::from_matrix(T);
}

/// The new keyframe of a loop check, as its verification reads it.
struct LoopQuery {
  const PinholeCamera& camera;
  const map::KeyFrame& keyframe;
  const std::vector<features::PointFeature>& features;
  const features::ScalePyramid& pyramid;

  /// Feature i can be matched: it has depth and is not excluded (a moving object's).
  bool usable(int i) const {
    return features[static_cast<std::size_t>(i)].has_depth() &&
           !keyframe.point_excluded(static_cast<std::size_t>(i));
  }
};

/// 3D-3D correspondences: the old place's map points (world) against the new keyframe's depth
/// points (camera), with the feature and the point each one pairs.
struct PlaceCorrespondences {
  std::vector<int> feature_of;
  std::vector<map::PointId> point_of;
  std::vector<Eigen::Vector3d> p_w, p_c;
};

/// The correspondences of the vocabulary matches (query: new keyframe, train: old keyframe).
PlaceCorrespondences correspondences(const LoopQuery& query, const map::Map& map,
                                     const map::KeyFrame& old,
                                     const std::vector<features::DescriptorMatch>& matches) {
  PlaceCorrespondences c;
  for (const auto& m : matches) {
    const auto& f = query.features[static_cast<std::size_t>(m.query)];
    const map::PointId p = old.landmarks[static_cast<std::size_t>(m.train)];
    c.feature_of.push_back(m.query);
    c.point_of.push_back(p);
    c.p_w.push_back(map.point(p)->p_w);
    c.p_c.push_back(query.camera.unproject(f.keypoint.uv.cast<double>(), f.depth));
  }
  return c;
}

/// How many correspondences the pose T explains (consistent()); their flags in `inlier` when
/// given.
int count_inliers(const LoopQuery& query, const PlaceCorrespondences& c, const SE3& T,
                  std::vector<bool>* inlier) {
  int n = 0;
  for (std::size_t k = 0; k < c.p_w.size(); ++k) {
    const bool ok =
        consistent(query.camera, query.features[static_cast<std::size_t>(c.feature_of[k])],
                   query.pyramid, T, c.p_w[k]);
    n += ok ? 1 : 0;
    if (inlier) (*inlier)[k] = ok;
  }
  return n;
}

/// A pose and how many correspondences it explains.
struct CountedPose {
  int inliers = 0;
  SE3 T;
};

/// RANSAC over triples of correspondences (random, seeded: deterministic): the pose explaining
/// the most of them.
CountedPose ransac_pose(const LoopQuery& query, const PlaceCorrespondences& c, std::uint32_t seed,
                        int iterations) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, c.p_w.size() - 1);
  CountedPose best;
  for (int it = 0; it < iterations; ++it) {
    const std::size_t a = pick(rng), b = pick(rng), d = pick(rng);
    if (a == b || b == d || a == d) continue;
    // Three points far enough apart and not on a line.
    const Eigen::Vector3d ab = c.p_c[b] - c.p_c[a], ad = c.p_c[d] - c.p_c[a];
    if (ab.cross(ad).norm() < 0.01) continue;
    const SE3 T = align({c.p_w[a], c.p_w[b], c.p_w[d]}, {c.p_c[a], c.p_c[b], c.p_c[d]});
    const int n = count_inliers(query, c, T, nullptr);
    if (n > best.inliers) {
      best.inliers = n;
      best.T = T;
    }
  }
  return best;
}

/// Refits the pose T on its inliers (twice: the set can grow), keeping a refit only when it
/// explains at least as many correspondences. `inlier` is working space (of c's size).
SE3 refit_on_inliers(const LoopQuery& query, const PlaceCorrespondences& c, SE3 T,
                     std::vector<bool>& inlier) {
  for (int round = 0; round < 2; ++round) {
    count_inliers(query, c, T, &inlier);
    std::vector<Eigen::Vector3d> from, to;
    for (std::size_t k = 0; k < c.p_w.size(); ++k)
      if (inlier[k]) {
        from.push_back(c.p_w[k]);
        to.push_back(c.p_c[k]);
      }
    if (from.size() < 3) break;
    const SE3 refit = align(from, to);
    if (count_inliers(query, c, refit, nullptr) >= count_inliers(query, c, T, nullptr)) T = refit;
  }
  return T;
}

/// Pose optimisation of the new keyframe from T against the (feature, map point) pairs.
optim::PoseOptimizationResult optimise_on(const LoopQuery& query, const map::Map& map,
                                          const std::vector<std::pair<int, map::PointId>>& pairs,
                                          const SE3& T, double depth_weight,
                                          const optim::PoseOptimizerOptions& options) {
  std::vector<optim::PoseObservation> observations;
  for (const auto& [feature, point] : pairs)
    observations.push_back(
        {map.point(point)->p_w, measurement_of(query.features[static_cast<std::size_t>(feature)],
                                               query.pyramid, depth_weight)});
  return optim::optimize_pose(query.camera, T, observations, options);
}

/// Guided search: the points of the old place (`candidate` and its best covisible keyframes)
/// projected into the new keyframe at loop.T_c_w, each matched to the closest free usable feature
/// by descriptor; adds the matches to `loop`.
void guided_search(const LoopQuery& query, const map::Map& map, map::KeyFrameId candidate,
                   LoopClosure& loop) {
  const SE3& T = loop.T_c_w;
  std::vector<bool> feature_used(query.features.size(), false);
  std::unordered_set<map::PointId> point_used;
  for (const auto& [feature, point] : loop.matches) {
    feature_used[static_cast<std::size_t>(feature)] = true;
    point_used.insert(point);
  }
  std::vector<int> nearby;
  std::vector<map::KeyFrameId> place = {candidate};
  for (map::KeyFrameId n : map.best_covisible(candidate, 10)) place.push_back(n);
  for (map::KeyFrameId k : place) {
    const map::KeyFrame* other = map.keyframe(k);
    if (other == nullptr) continue;
    for (std::size_t j = 0; j < other->landmarks.size(); ++j) {
      const map::PointId pid = other->landmarks[j];
      if (pid == map::kNoId || other->point_excluded(j) || point_used.count(pid) != 0) continue;
      const map::MapPoint* mp = map.point(pid);
      if (mp == nullptr) continue;
      point_used.insert(pid);
      const Eigen::Vector3d pc = T * mp->p_w;
      if (pc.z() <= 0.0) continue;
      const Eigen::Vector2d uv = query.camera.project(pc);
      if (!query.camera.in_image(uv)) continue;
      const int level = query.pyramid.predict_level(pc.norm(), std::max(mp->max_distance, 1e-3));
      query.keyframe.features->grid.query(
          static_cast<float>(uv.x()), static_cast<float>(uv.y()),
          static_cast<float>(3.0 * query.pyramid.scale[static_cast<std::size_t>(level)]),
          std::max(0, level - 1), level + 1, nearby);
      int best_distance = 51;
      int best_feature = -1;
      for (int i : nearby) {
        if (feature_used[static_cast<std::size_t>(i)] || !query.usable(i)) continue;
        const features::PointFeature& f = query.features[static_cast<std::size_t>(i)];
        const int d = features::hamming_distance(mp->descriptor, f.descriptor);
        if (d < best_distance && consistent(query.camera, f, query.pyramid, T, mp->p_w)) {
          best_distance = d;
          best_feature = i;
        }
      }
      if (best_feature < 0) continue;
      feature_used[static_cast<std::size_t>(best_feature)] = true;
      loop.matches.emplace_back(best_feature, pid);
    }
  }
}

}  // namespace

LoopCloser::LoopCloser(const PinholeCamera& camera, const LoopOptions& options,
                       const TrackerOptions& tracker_options, const MapperOptions& mapper_options,
                       std::shared_ptr<const place::Vocabulary> vocabulary, const map::Map& map,
                       LocalMapper& mapper)
    : camera_(camera),
      options_(options),
      tracker_options_(tracker_options),
      mapper_options_(mapper_options),
      vocabulary_(std::move(vocabulary)),
      map_(map),
      mapper_(mapper) {}

LoopCloser::~LoopCloser() { finish(); }

void LoopCloser::start(int niceness) {
  std::lock_guard<std::mutex> guard(queue_mutex_);
  if (thread_.joinable()) return;
  stop_ = false;
  thread_ = std::thread([this, niceness] {
    set_current_thread_name("mcslam-loop");
    lower_current_thread_priority(niceness);  // best effort
    try {
      run();
    } catch (...) {
      failure_.set(std::current_exception());
      std::lock_guard<std::mutex> guard(queue_mutex_);
      queue_.clear();
    }
  });
}

void LoopCloser::enqueue(map::KeyFrameId keyframe) {
  {
    std::lock_guard<std::mutex> guard(queue_mutex_);
    if (failure_.failed()) return;  // the thread has stopped: System reports its failure
    queue_.push_back(keyframe);
  }
  queue_cv_.notify_one();
}

void LoopCloser::finish() {
  {
    std::lock_guard<std::mutex> guard(queue_mutex_);
    if (!thread_.joinable()) return;
    stop_ = true;
  }
  abort_ba_ = true;
  queue_cv_.notify_one();
  thread_.join();
}

void LoopCloser::run() {
  for (;;) {
    map::KeyFrameId id = map::kNoId;
    {
      std::unique_lock<std::mutex> lock(queue_mutex_);
      queue_cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;
      id = queue_.front();
      queue_.pop_front();
    }
    process(id);
  }
}

LoopStatistics LoopCloser::statistics() const {
  std::lock_guard<std::mutex> guard(stats_mutex_);
  return stats_;
}

void LoopCloser::process(map::KeyFrameId keyframe) {
  Stopwatch watch;
  if (fail_after_keyframes_ >= 0 &&
      static_cast<std::int64_t>(keyframes_seen_) >= fail_after_keyframes_)
    throw std::runtime_error("failure injected after " + std::to_string(keyframes_seen_) +
                             " keyframes (--inject-failure)");
  const auto candidates = detect(keyframe);
  {
    std::lock_guard<std::mutex> guard(stats_mutex_);
    stats_.detection_ms.push_back(watch.elapsed_ms());
  }
  for (const auto& [candidate, score] : candidates) {
    LoopEvent event;
    event.keyframe = keyframe;
    event.matched = candidate;
    event.score = score;
    watch.restart();
    std::optional<LoopClosure> loop = verify(keyframe, candidate, event);
    event.verify_ms = watch.elapsed_ms();
    if (!loop && event.matches < options_.min_matches) {
      // Too unlike the keyframe to try geometry: counted, not listed.
      std::lock_guard<std::mutex> guard(stats_mutex_);
      ++stats_.unmatched_candidates;
      continue;
    }
    if (loop) {
      bool applied = false;
      mapper_.run_task([&] { applied = mapper_.close_loop(*loop, options_, event); });
      event.accepted = applied;
    }
    {
      std::lock_guard<std::mutex> guard(stats_mutex_);
      stats_.events.push_back(event);
      if (event.pose_graph_failed) ++stats_.pose_graph_failed;
    }
    if (event.accepted) {
      last_loop_ = keyframe;
      keyframes_at_last_loop_ = keyframes_seen_;
      groups_.clear();
      if (options_.full_ba_iterations > 0) full_bundle_adjustment();
      break;
    }
  }
}

std::vector<std::pair<map::KeyFrameId, double>> LoopCloser::detect(map::KeyFrameId id) {
  ++keyframes_seen_;
  std::vector<Group> groups;
  std::vector<std::pair<map::KeyFrameId, double>> out;
  const auto finish_with = [&](std::vector<Group> next) {
    groups_ = std::move(next);
    return out;
  };
  auto lock = map_.read_lock();
  const map::KeyFrame* kf = map_.keyframe(id);
  const place::Database* database = map_.database();
  if (kf == nullptr || !kf->bow || database == nullptr) return finish_with({});
  if (map_.num_keyframes() < static_cast<std::size_t>(options_.min_keyframes) ||
      (last_loop_ != map::kNoId &&
       keyframes_seen_ <
           keyframes_at_last_loop_ + static_cast<std::size_t>(options_.min_keyframes)))
    return finish_with({});
  // The place must look more like the candidate than like the keyframe's own neighbours do.
  std::unordered_set<map::KeyFrameId> connected = {id};
  double min_score = 1.0;
  for (const auto& [other, weight] : kf->covisibility) {
    connected.insert(other);
    const map::KeyFrame* n = map_.keyframe(other);
    if (n == nullptr || !n->bow || weight < 15) continue;
    min_score = std::min(min_score, place::score(kf->bow->bow, n->bow->bow));
  }
  if (connected.size() == 1) return finish_with({});
  const auto results = database->query(kf->bow->bow, 0, min_score, [&](place::EntryId e) {
    return e >= id || connected.count(e) != 0;
  });
  if (results.empty()) return finish_with({});
  // Group each result with its covisible keyframes that also scored; keep groups within 75 %
  // of the best group's accumulated score.
  std::unordered_map<map::KeyFrameId, double> scores;
  for (const auto& r : results) scores.emplace(r.id, r.score);
  struct Scored {
    map::KeyFrameId best = map::kNoId;
    double best_score = 0.0;
    double accumulated = 0.0;
    std::vector<map::KeyFrameId> members;
  };
  std::vector<Scored> scored;
  double best_accumulated = 0.0;
  for (const auto& r : results) {
    Scored s{r.id, r.score, r.score, {r.id}};
    for (map::KeyFrameId n : map_.best_covisible(r.id, 10)) {
      s.members.push_back(n);
      const auto it = scores.find(n);
      if (it == scores.end()) continue;
      s.accumulated += it->second;
      if (it->second > s.best_score) {
        s.best_score = it->second;
        s.best = n;
      }
    }
    best_accumulated = std::max(best_accumulated, s.accumulated);
    scored.push_back(std::move(s));
  }
  std::unordered_set<map::KeyFrameId> taken;
  for (Scored& s : scored) {
    if (s.accumulated < 0.75 * best_accumulated || !taken.insert(s.best).second) continue;
    Group g;
    g.members = s.members;
    std::sort(g.members.begin(), g.members.end());
    // Consistent with a group of the previous keyframe when they share a keyframe.
    for (const Group& previous : groups_) {
      std::vector<map::KeyFrameId> shared;
      std::set_intersection(g.members.begin(), g.members.end(), previous.members.begin(),
                            previous.members.end(), std::back_inserter(shared));
      if (!shared.empty()) g.consistency = std::max(g.consistency, previous.consistency + 1);
    }
    if (g.consistency + 1 >= options_.min_consistency) out.emplace_back(s.best, s.best_score);
    groups.push_back(std::move(g));
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return a.second > b.second || (a.second == b.second && a.first < b.first);
  });
  return finish_with(std::move(groups));
}

std::optional<LoopClosure> LoopCloser::verify(map::KeyFrameId id, map::KeyFrameId candidate,
                                              LoopEvent& event) const {
  auto lock = map_.read_lock();
  const map::KeyFrame* kf = map_.keyframe(id);
  const map::KeyFrame* old = map_.keyframe(candidate);
  if (kf == nullptr || old == nullptr || !kf->bow || !old->bow) {
    event.reason = "keyframe culled";
    return std::nullopt;
  }
  event.timestamp = kf->timestamp;
  event.matched_timestamp = old->timestamp;
  const LoopQuery query{camera_, *kf, kf->features->points, *kf->features->pyramid};
  const auto matches = place::match_by_words(
      kf->bow->direct, kf->features->point_descriptors(), old->bow->direct,
      old->features->point_descriptors(), place::WordMatchOptions{},
      [&](int i) { return query.usable(i); },
      [&](int j) {
        const map::PointId p = old->landmarks[static_cast<std::size_t>(j)];
        return p != map::kNoId && map_.point(p) != nullptr &&
               !old->point_excluded(static_cast<std::size_t>(j));
      });
  event.matches = static_cast<int>(matches.size());
  if (event.matches < options_.min_matches) {
    event.reason = "too few matches through the vocabulary";
    return std::nullopt;
  }
  const PlaceCorrespondences c = correspondences(query, map_, *old, matches);
  const CountedPose ransac = ransac_pose(
      query, c, static_cast<std::uint32_t>(id * 7919 + candidate), options_.ransac_iterations);
  event.ransac_inliers = ransac.inliers;
  if (ransac.inliers < options_.min_ransac_inliers) {
    event.reason = "too few RANSAC inliers";
    return std::nullopt;
  }
  std::vector<bool> inlier(c.p_w.size(), false);
  SE3 best_T = refit_on_inliers(query, c, ransac.T, inlier);
  count_inliers(query, c, best_T, &inlier);
  // Then the pose that best explains the inliers' image positions and depths (RANSAC's fit weighs
  // every 3D point alike, though depth noise grows with the square of the distance).
  {
    std::vector<std::pair<int, map::PointId>> pairs;
    for (std::size_t k = 0; k < c.p_w.size(); ++k)
      if (inlier[k]) pairs.emplace_back(c.feature_of[k], c.point_of[k]);
    // Without a usable solution the RANSAC pose stands; the inlier count below judges it.
    if (const auto refined = optimise_on(query, map_, pairs, best_T, tracker_options_.depth_weight,
                                         tracker_options_.pose);
        !refined.failed)
      best_T = refined.T_c_w;
    count_inliers(query, c, best_T, &inlier);
  }
  LoopClosure loop;
  loop.keyframe = id;
  loop.matched = candidate;
  loop.T_c_w = best_T;
  for (std::size_t k = 0; k < c.p_w.size(); ++k)
    if (inlier[k]) loop.matches.emplace_back(c.feature_of[k], c.point_of[k]);
  guided_search(query, map_, candidate, loop);
  // The final pose from every match; outliers leave.
  const optim::PoseOptimizationResult refined = optimise_on(
      query, map_, loop.matches, best_T, tracker_options_.depth_weight, tracker_options_.pose);
  loop.T_c_w = refined.T_c_w;
  std::vector<std::pair<int, map::PointId>> kept;
  for (std::size_t k = 0; k < loop.matches.size(); ++k)
    if (refined.inlier[k]) kept.push_back(loop.matches[k]);
  loop.matches = std::move(kept);
  event.inliers = static_cast<int>(loop.matches.size());
  if (event.inliers < options_.min_inliers) {
    event.reason = "too few inliers after the guided search";
    return std::nullopt;
  }
  return loop;
}

void LoopCloser::full_bundle_adjustment() {
  Stopwatch watch;
  {
    std::lock_guard<std::mutex> guard(queue_mutex_);
    if (stop_) return;  // the run is ending: System::finish adjusts the whole map itself
    abort_ba_ = false;
  }
  MapAdjustment adjustment;
  {
    auto lock = map_.read_lock();
    std::vector<map::KeyFrameId> all;
    for (const auto& kv : map_.keyframes()) all.push_back(kv.first);
    std::sort(all.begin(), all.end());
    if (all.size() < 2) return;
    adjustment = build_adjustment(map_, all, mapper_options_, tracker_options_);
  }
  if (adjustment.empty()) return;
  const std::vector<SE3> before = adjustment.problem.poses;
  const std::vector<Eigen::Vector3d> points_before = adjustment.problem.points;
  optim::BundleAdjustmentOptions ba;
  ba.robust_iterations = options_.full_ba_iterations;
  ba.refine_iterations = options_.full_ba_iterations;
  const auto result = optim::bundle_adjust(camera_, adjustment.problem, ba, &abort_ba_);
  if (!result.aborted && !result.failed) {
    const map::MapCorrection correction = correction_of(adjustment, result, before, points_before);
    mapper_.run_task([&] { mapper_.correct(correction); });
  }
  std::lock_guard<std::mutex> guard(stats_mutex_);
  if (result.aborted) {
    ++stats_.full_ba_aborted;
  } else if (result.failed) {
    ++stats_.full_ba_failed;
  } else {
    ++stats_.full_ba_runs;
    stats_.full_ba_ms.push_back(watch.elapsed_ms());
  }
}

}  // namespace mcslam::slam
