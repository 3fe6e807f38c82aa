#pragma once
// An analytic box world for the mapping tests: a room (the inside of an axis-aligned box: floor,
// ceiling, four walls) with axis-aligned boxes in it, rendered to exact depth by ray casting.
// World frame: z up. Camera frame: x right, y down, z forward.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <vector>

#include "mcslam/core/camera.hpp"
#include "mcslam/core/se3.hpp"
#include "mcslam/mapping/evaluation.hpp"
#include "mcslam/mapping/occupancy_map.hpp"

namespace mcslam::test {

struct WorldBox {
  Eigen::Vector3d min, max;
  bool dynamic = false;  ///< its pixels are marked in the dynamic mask
  cv::Vec3b bgr{40, 80, 200};
  bool mover = false;  ///< its pixels are marked in the mover mask
  bool contains(const Eigen::Vector3d& p, double margin = 0.0) const {
    return (p.array() >= min.array() - margin).all() && (p.array() <= max.array() + margin).all();
  }
};

/// The room's surfaces are deliberately off the 5 cm voxel boundaries (a real floor is never
/// exactly on one), so that a surface lies inside one layer of voxels.
struct BoxWorld {
  Eigen::Vector3d room_min{-0.013, -0.021, 0.012};
  Eigen::Vector3d room_max{5.987, 4.979, 2.812};
  std::vector<WorldBox> boxes;

  /// Depth (z of the camera frame) along the ray, and whether a dynamic box is hit.
  void cast(const Eigen::Vector3d& o, const Eigen::Vector3d& dir, double& t_hit, int& box) const {
    // Leaving the room: the nearest exit plane along the ray.
    t_hit = std::numeric_limits<double>::infinity();
    box = -1;
    for (int a = 0; a < 3; ++a) {
      if (dir[a] > 1e-12) t_hit = std::min(t_hit, (room_max[a] - o[a]) / dir[a]);
      if (dir[a] < -1e-12) t_hit = std::min(t_hit, (room_min[a] - o[a]) / dir[a]);
    }
    for (std::size_t b = 0; b < boxes.size(); ++b) {
      double t0 = 0.0, t1 = t_hit;
      for (int a = 0; a < 3 && t0 <= t1; ++a) {
        if (std::abs(dir[a]) < 1e-12) {
          if (o[a] < boxes[b].min[a] || o[a] > boxes[b].max[a]) t0 = t1 + 1.0;
          continue;
        }
        double ta = (boxes[b].min[a] - o[a]) / dir[a], tb = (boxes[b].max[a] - o[a]) / dir[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
      }
      if (t0 <= t1 && t0 > 0.0 && t0 < t_hit) {
        t_hit = t0;
        box = static_cast<int>(b);
      }
    }
  }

  mapping::KeyframeDepth render(mapping::KeyframeId id, const SE3& T_w_c,
                                const PinholeCamera& cam) const {
    mapping::KeyframeDepth kf;
    kf.id = id;
    kf.T_w_c = T_w_c;
    kf.camera = cam;
    kf.depth = cv::Mat(cam.height, cam.width, CV_32FC1);
    kf.dynamic_mask = cv::Mat::zeros(cam.height, cam.width, CV_8UC1);
    kf.mover_mask = cv::Mat::zeros(cam.height, cam.width, CV_8UC1);
    kf.colour = cv::Mat(cam.height, cam.width, CV_8UC3);
    const Eigen::Matrix3d R = T_w_c.rotation();
    const Eigen::Vector3d o = T_w_c.translation();
    for (int v = 0; v < cam.height; ++v)
      for (int u = 0; u < cam.width; ++u) {
        // The ray at unit depth, so that t is the depth.
        const Eigen::Vector3d dir =
            R * Eigen::Vector3d((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);
        double t;
        int box;
        cast(o, dir, t, box);
        kf.depth.at<float>(v, u) = static_cast<float>(t);
        const bool dynamic = box >= 0 && boxes[box].dynamic;
        kf.dynamic_mask.at<std::uint8_t>(v, u) = dynamic ? 255 : 0;
        kf.mover_mask.at<std::uint8_t>(v, u) = box >= 0 && boxes[box].mover ? 255 : 0;
        kf.colour.at<cv::Vec3b>(v, u) = box >= 0 ? boxes[box].bgr : cv::Vec3b(180, 180, 180);
      }
    return kf;
  }

  /// The room's six planes (normals pointing into the room) and the static boxes.
  std::vector<mapping::StaticSurface> static_surfaces() const {
    // The room: a box seen from inside.
    std::vector<mapping::StaticSurface> s = {mapping::StaticSurface::box(
        SE3(Eigen::Quaterniond::Identity(), 0.5 * (room_min + room_max)),
        0.5 * (room_max - room_min))};
    for (const auto& b : boxes)
      if (!b.dynamic && !b.mover)
        s.push_back(mapping::StaticSurface::box(
            SE3(Eigen::Quaterniond::Identity(), 0.5 * (b.min + b.max)), 0.5 * (b.max - b.min)));
    return s;
  }
};

/// A camera at `position` looking along world yaw (0: +x), pitched down by `pitch` (radians).
inline SE3 look(const Eigen::Vector3d& position, double yaw, double pitch = 0.25) {
  // Camera axes for yaw 0, no pitch: z forward = +x, x right = -y, y down = -z.
  Eigen::Matrix3d base;
  base.col(0) = -Eigen::Vector3d::UnitY();
  base.col(1) = -Eigen::Vector3d::UnitZ();
  base.col(2) = Eigen::Vector3d::UnitX();
  const Eigen::Matrix3d R = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                            base *
                            Eigen::AngleAxisd(-pitch, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return SE3(R, position);
}

}  // namespace mcslam::test
