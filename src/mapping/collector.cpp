#include "mapping/collector.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace mcslam::mapping::detail {

/// Notes a free ray from the keyframe's origin to the voxel holding `to` (that voxel not freed);
/// cast_rays() casts one ray per such voxel, weighted by the samples that end there: nearby
/// samples of a keyframe (9 per voxel side at 1 m with the default step) would cross the same
/// voxels again.
void Collector::add_free(const octomap::OcTree& tree, const Eigen::Vector3d& to) {
  octomap::OcTreeKey end;
  if (!tree.coordToKeyChecked(to.x(), to.y(), to.z(), end)) return;
  marks_.count_end(marks_.mark(end, kRayEnd).entry);
}

/// Sets the marks' window to the voxels the keyframe's samples can touch: the box around its
/// view's pyramid, from the origin to depth max_range (hits are nearer, rays end there), and a
/// voxel more each way.
void Collector::set_view_window(const octomap::OcTree& tree, const OccupancyOptions& options,
                                const KeyframeSamples& s) {
  const Eigen::Matrix3d R = s.T_w_c.rotation();
  const Eigen::Vector3d o = s.T_w_c.translation();
  Eigen::Vector3d lo = o, hi = o;
  const int last_i = s.depth_mm.cols - 1, last_j = s.depth_mm.rows - 1;
  for (const auto& [i, j] : {std::pair{0, 0}, {last_i, 0}, {0, last_j}, {last_i, last_j}}) {
    const Eigen::Vector3d corner = o + options.max_range * (R * s.ray(i, j));
    lo = lo.cwiseMin(corner);
    hi = hi.cwiseMax(corner);
  }
  lo.array() -= options.resolution;
  hi.array() += options.resolution;
  octomap::OcTreeKey lo_key, hi_key;
  if (tree.coordToKeyChecked(lo.x(), lo.y(), lo.z(), lo_key) &&
      tree.coordToKeyChecked(hi.x(), hi.y(), hi.z(), hi_key))
    marks_.set_window(lo_key, hi_key);
}

/// Frees the voxels crossed by the rays add_free() noted, from `origin` to the centre of each
/// end voxel, each crossing counted once per sample whose ray ends there where a spread hit
/// needs the count (Impl::apply reads it there only).
void Collector::cast_rays(const octomap::OcTree& tree, const Eigen::Vector3d& origin) {
  const octomap::point3d from = to_point(origin);
  const std::size_t noted = marks_.entries().size();
  marks_.begin_crossings(kCrossed, kSpreadHit);
  for (std::size_t e = 0; e < noted; ++e) {
    const KeyMarks::Entry end = marks_.entries()[e];  // a copy: marking may grow them
    if ((end.roles & kRayEnd) == 0) continue;
    walk_ray(tree, from, tree.keyToCoord(end.key),
             [&](const octomap::OcTreeKey& key) { marks_.cross(key, end.ends); });
  }
  marks_.end_crossings();
}

/// The free ray and the hit of the sample at (i, j), seen from the camera at (R, o).
void Collector::add_sample(const octomap::OcTree& tree, const OccupancyOptions& options,
                           const KeyframeSamples& s, const Eigen::Matrix3d& R,
                           const Eigen::Vector3d& o, int i, int j) {
  const std::uint16_t mm = s.depth_mm.at<std::uint16_t>(j, i);
  if (mm == 0) return;
  const double z = 1e-3 * mm;
  // The ray at unit depth, in the world frame: p_w = o + z * dir_z.
  const Eigen::Vector3d dir_z = R * s.ray(i, j);
  if (z > options.max_range) {
    add_free(tree, o + options.max_range * dir_z);
    return;
  }
  const double sigma = options.depth_sigma(z);
  const double z_free = z - options.free_margin_sigmas * sigma;
  if (z_free > 0.0) add_free(tree, o + z_free * dir_z);
  const std::uint8_t kind = s.kind.at<std::uint8_t>(j, i);
  if (kind == KeyframeSamples::kDynamic) return;
  const bool mover = kind == KeyframeSamples::kMover;
  const cv::Vec3b* bgr = s.colour.empty() ? nullptr : &s.colour.at<cv::Vec3b>(j, i);
  add_hit(tree, o, dir_z, z, sigma, [&](const octomap::OcTreeKey& k, bool spread) {
    const std::uint8_t role = mover ? kMoverHit : spread ? kSpreadHit : kHit;
    const std::size_t entry = marks_.mark(k, role).entry;
    if (role == kSpreadHit) marks_.count_spread(entry);
    if (role == kHit) marks_.count_hit(entry);
    if (bgr == nullptr || spread) return;
    if (entry >= colours_.size()) colours_.resize(marks_.entries().size());
    ColourSum& c = colours_[entry];
    c.b += (*bgr)[0];
    c.g += (*bgr)[1];
    c.r += (*bgr)[2];
    ++c.n;
  });
}

/// Drops the hits of the voxels whose samples are the depth noise's tail behind the surface
/// in the voxel in front of them (OccupancyOptions::tail_yield_ratio).
void Collector::drop_noise_tails(const octomap::OcTree& tree, const OccupancyOptions& options,
                                 const Eigen::Vector3d& origin) {
  const double ratio = options.effective_tail_yield_ratio();
  if (!(ratio > 0.0)) return;
  const double res = tree.getResolution();
  const std::size_t n = marks_.entries().size();
  for (std::size_t e = 0; e < n; ++e) {
    const KeyMarks::Entry& entry = marks_.entries()[e];
    if ((entry.roles & kHit) == 0) continue;
    const octomap::point3d c = tree.keyToCoord(entry.key);
    const Eigen::Vector3d centre(c.x(), c.y(), c.z());
    const Eigen::Vector3d ray = centre - origin;
    const double distance = ray.norm();
    // The tail reaches 3 sigma_z behind the surface: up to that many voxels in front.
    const int reach =
        std::max(1, static_cast<int>(std::ceil(3.0 * options.depth_sigma(distance) / res)));
    const Eigen::Vector3d step = (res / distance) * ray;
    std::uint32_t most = 0;  // the most samples in a voxel in front within reach
    for (int k = 1; k <= reach; ++k) {
      const Eigen::Vector3d p = centre - k * step;
      octomap::OcTreeKey key;
      if (!tree.coordToKeyChecked(p.x(), p.y(), p.z(), key) || key == entry.key) continue;
      if (const auto front = marks_.find_entry(key))
        most = std::max(most, marks_.entries()[*front].hits);
    }
    if (static_cast<double>(entry.hits) < ratio * most) marks_.drop_role(e, kHit | kSpreadHit);
  }
}

void Collector::collect(const octomap::OcTree& tree, const OccupancyOptions& options,
                        const KeyframeSamples& s) {
  marks_.clear();
  colours_.clear();
  const Eigen::Matrix3d R = s.T_w_c.rotation();
  const Eigen::Vector3d o = s.T_w_c.translation();
  set_view_window(tree, options, s);
  for (int j = 0; j < s.depth_mm.rows; ++j)
    for (int i = 0; i < s.depth_mm.cols; ++i) add_sample(tree, options, s, R, o, i, j);
  cast_rays(tree, o);
  drop_noise_tails(tree, options, o);
}

}  // namespace mcslam::mapping::detail
