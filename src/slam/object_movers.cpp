// Object stages for motion without a box: features whose position contradicts the camera's
// motion (seeds), grown into regions of neighbouring features at a similar depth; and the
// moving regions carried on from frame to frame.

#include <algorithm>
#include <cmath>

#include "mcslam/slam/object_stages.hpp"
#include "object_geometry.hpp"

namespace mcslam::slam {

MotionSeeds motion_seeds(const features::FrameFeatures& features,
                         const std::vector<MotionEvidence>& evidence,
                         const std::vector<std::uint8_t>& excluded, const PinholeCamera& camera,
                         const DynamicsOptions& opt) {
  const auto& points = features.points;
  const std::size_t n = points.size();
  MotionSeeds out;
  out.seed.assign(n, 0);
  out.measured.assign(n, 0);
  out.landmark.assign(n, map::kNoId);
  for (const MotionEvidence& e : evidence) {
    const auto i = static_cast<std::size_t>(e.point);
    if (i >= n || !points[i].has_depth() || (i < excluded.size() && excluded[i])) continue;
    const auto& f = points[i];
    const Eigen::Vector3d seen = camera.unproject(f.keypoint.uv.cast<double>(), f.depth);
    const double limit = opt.mover_displacement + opt.mover_relative * f.depth;
    out.measured[i] = 1;
    if (e.landmark != map::kNoId) out.landmark[i] = e.landmark;
    if (e.expected_c.z() <= 1e-6) continue;
    // Off in the image as well as in depth: a depth error alone (dark or shiny surfaces, mixed
    // pixels at an edge) moves a point along its ray, not across the image.
    const double scale = features.pyramid->scale[static_cast<std::size_t>(f.keypoint.level)];
    const double pixels =
        (camera.project(e.expected_c) - f.keypoint.uv.cast<double>()).norm() / scale;
    if (!out.seed[i] && (seen - e.expected_c).norm() > limit && pixels > opt.mover_pixels) {
      out.seed[i] = 1;
      ++out.count;
    }
  }
  return out;
}

std::vector<std::uint8_t> moving_planes(const features::FrameFeatures& features,
                                        const MotionSeeds& seeds, const DynamicsOptions& options) {
  const std::size_t n_planes = features.planes.size();
  std::vector<int> seed_count(n_planes, 0), with_evidence(n_planes, 0);
  for (std::size_t i = 0; i < features.points.size(); ++i) {
    const int k = features.points[i].plane;
    if (k < 0 || static_cast<std::size_t>(k) >= n_planes || !seeds.measured[i]) continue;
    ++with_evidence[static_cast<std::size_t>(k)];
    seed_count[static_cast<std::size_t>(k)] += seeds.seed[i];
  }
  std::vector<std::uint8_t> moving(n_planes, 0);
  for (std::size_t k = 0; k < n_planes; ++k)
    moving[k] = seed_count[k] >= options.mover_min_seeds &&
                seed_count[k] >= options.mover_seed_share * with_evidence[k];
  return moving;
}

RegionNodes region_nodes(const features::FrameFeatures& features, const MotionSeeds& seeds,
                         const std::vector<std::uint8_t>& excluded,
                         const std::vector<std::uint8_t>& moving_plane) {
  // A point on a frame plane (floor, wall, desk top) joins a region only as a seed, so that a
  // region never spreads along the floor a person stands on; unless the plane itself is seen to
  // move: the flat side of a box carried, a door, a cart.
  const auto& points = features.points;
  RegionNodes out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].has_depth() || (i < excluded.size() && excluded[i])) continue;
    ++out.with_depth;
    if (seeds.seed[i] || points[i].plane < 0 ||
        object_geometry::on_moving_plane(points[i], moving_plane))
      out.nodes.push_back(i);
  }
  return out;
}

std::vector<std::vector<std::size_t>> connected_regions(const features::FrameFeatures& features,
                                                        const RegionNodes& nodes,
                                                        const MotionSeeds& seeds,
                                                        const DynamicsOptions& opt) {
  const auto& points = features.points;
  std::vector<std::uint8_t> taken(points.size(), 0);
  const double r2 = opt.mover_link_radius * opt.mover_link_radius;
  std::vector<std::vector<std::size_t>> regions;
  std::vector<std::size_t> stack;
  for (std::size_t s0 : nodes.nodes) {
    if (!seeds.seed[s0] || taken[s0]) continue;
    taken[s0] = 1;
    stack.assign(1, s0);
    std::vector<std::size_t> members;
    while (!stack.empty()) {
      const std::size_t a = stack.back();
      stack.pop_back();
      members.push_back(a);
      const auto& pa = points[a];
      for (std::size_t b : nodes.nodes) {
        if (taken[b]) continue;
        const auto& pb = points[b];
        if ((pa.keypoint.uv - pb.keypoint.uv).cast<double>().squaredNorm() > r2) continue;
        if (std::abs(pa.depth - pb.depth) > opt.mover_link_depth) continue;
        taken[b] = 1;
        stack.push_back(b);
      }
    }
    regions.push_back(std::move(members));
  }
  return regions;
}

std::optional<perception::Detection> mover_region(const features::FrameFeatures& features,
                                                  const std::vector<std::size_t>& members,
                                                  const MotionSeeds& seeds, int with_depth,
                                                  const DynamicsOptions& opt) {
  int region_seeds = 0, region_measured = 0;
  for (std::size_t m : members) {
    region_seeds += seeds.seed[m];
    region_measured += seeds.measured[m];
  }
  if (region_seeds < opt.mover_min_seeds || region_seeds < opt.mover_seed_share * region_measured ||
      members.size() * 2 > static_cast<std::size_t>(with_depth))
    return std::nullopt;
  float x0 = 1e9f, y0 = 1e9f, x1 = -1e9f, y1 = -1e9f;
  for (std::size_t m : members) {
    const auto& uv = features.points[m].keypoint.uv;
    x0 = std::min(x0, uv.x());
    y0 = std::min(y0, uv.y());
    x1 = std::max(x1, uv.x());
    y1 = std::max(y1, uv.y());
  }
  perception::Detection d;
  d.box = cv::Rect2f(x0, y0, x1 - x0 + 1.0f, y1 - y0 + 1.0f);
  d.class_name = kMovingRegionClass;
  d.class_id = -1;
  d.score = static_cast<float>(region_seeds) / static_cast<float>(std::max(1, region_measured));
  return d;
}

std::vector<MovingRegion> surviving_movers(const std::vector<ObjectBox>& boxes,
                                           const std::vector<ObjectState>& state,
                                           const std::vector<ObjectDecision>& decisions,
                                           std::uint64_t frame_id, int life) {
  std::vector<MovingRegion> kept;
  for (std::size_t b = 0; b < boxes.size(); ++b) {
    if (boxes[b].source != BoxSource::kMover) continue;
    if (state[b] == ObjectState::kStatic) continue;
    MovingRegion m;
    m.detection = boxes[b].detection;
    m.frame = frame_id;
    m.unconfirmed = decisions[b].dynamic ? 0 : boxes[b].unconfirmed + 1;
    m.flat = boxes[b].flat;
    m.depth = boxes[b].depth > 0.0f ? boxes[b].depth : boxes[b].last_depth;
    if (m.unconfirmed < life) kept.push_back(m);
  }
  return kept;
}

}  // namespace mcslam::slam
