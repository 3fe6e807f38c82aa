#include "mcslam/slam/occupancy.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "mcslam/slam/objects.hpp"

namespace mcslam::slam {

std::vector<DynamicRegion> object_regions(const std::vector<ObjectReport>& objects,
                                          ObjectState state) {
  std::vector<DynamicRegion> out;
  for (const ObjectReport& o : objects)
    if (o.state == state) out.push_back({o.detection.box, o.depth_near, o.depth_far, o.track_id});
  return out;
}

cv::Mat region_mask(const cv::Mat& depth, const std::vector<DynamicRegion>& regions,
                    double depth_margin) {
  if (regions.empty() || depth.empty() || depth.type() != CV_32FC1) return {};
  cv::Mat mask(depth.size(), CV_8UC1, cv::Scalar(0));
  const cv::Rect image(0, 0, depth.cols, depth.rows);
  for (const DynamicRegion& r : regions) {
    const cv::Rect box =
        cv::Rect(static_cast<int>(std::floor(r.box.x)), static_cast<int>(std::floor(r.box.y)),
                 static_cast<int>(std::ceil(r.box.width)) + 1,
                 static_cast<int>(std::ceil(r.box.height)) + 1) &
        image;
    if (box.empty()) continue;
    const bool banded = r.depth_far > 0.0f;
    const float near =
        banded ? std::max(0.0f, r.depth_near - static_cast<float>(depth_margin)) : 0.0f;
    const float far = banded ? r.depth_far + static_cast<float>(depth_margin) : 0.0f;
    for (int y = box.y; y < box.y + box.height; ++y) {
      const float* z = depth.ptr<float>(y);
      std::uint8_t* m = mask.ptr<std::uint8_t>(y);
      for (int x = box.x; x < box.x + box.width; ++x) {
        // No depth: nothing is inserted there anyway; within the band (or without one): the
        // object; beyond it: the background seen past the object, static.
        const bool object = !banded || !(z[x] > 0.0f) || (z[x] >= near && z[x] <= far);
        if (object) m[x] = 255;
      }
    }
  }
  return mask;
}

std::optional<std::pair<Eigen::Vector3d, Eigen::Vector3d>> world_box(
    const PinholeCamera& camera, const cv::Mat& depth, const DynamicRegion& region,
    const SE3& T_w_c, double depth_margin, int step) {
  if (depth.empty() || depth.type() != CV_32FC1) return std::nullopt;
  const cv::Rect box = cv::Rect(static_cast<int>(std::floor(region.box.x)),
                                static_cast<int>(std::floor(region.box.y)),
                                static_cast<int>(std::ceil(region.box.width)),
                                static_cast<int>(std::ceil(region.box.height))) &
                       cv::Rect(0, 0, depth.cols, depth.rows);
  const bool banded = region.depth_far > 0.0f;
  const double near = banded ? region.depth_near - depth_margin : 0.0;
  const double far = banded ? region.depth_far + depth_margin : 1e9;
  std::array<std::vector<double>, 3> axes;
  for (int y = box.y; y < box.y + box.height; y += step) {
    const float* row = depth.ptr<float>(y);
    for (int x = box.x; x < box.x + box.width; x += step) {
      const double z = row[x];
      if (!(z > 0.0) || z < near || z > far) continue;
      const Eigen::Vector3d p_c((x - camera.cx) * z / camera.fx, (y - camera.cy) * z / camera.fy,
                                z);
      const Eigen::Vector3d p_w = T_w_c * p_c;
      for (int a = 0; a < 3; ++a) axes[a].push_back(p_w[a]);
    }
  }
  if (axes[0].size() < 10) return std::nullopt;
  Eigen::Vector3d lo, hi;
  for (int a = 0; a < 3; ++a) {
    std::vector<double>& v = axes[a];
    const auto at = [&v](double q) {
      const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(v.size() - 1));
      std::nth_element(v.begin(), v.begin() + k, v.end());
      return v[static_cast<std::size_t>(k)];
    };
    lo[a] = at(0.05);
    hi[a] = at(0.95);
  }
  return std::make_pair(lo, hi);
}

std::vector<mapping::FloorPlane> floor_candidates(const map::Map& map, double max_tilt_deg,
                                                  std::size_t min_keyframes) {
  std::vector<mapping::FloorPlane> out;
  if (map.keyframes().empty()) return out;
  const map::KeyFrame* first = nullptr;
  for (const auto& [id, kf] : map.keyframes())
    if (!first || id < first->id) first = &kf;
  const SE3 T_w_c = first->T_w_c();
  const Eigen::Vector3d up = -(T_w_c.rotation() * Eigen::Vector3d::UnitY());
  const Eigen::Vector3d camera = T_w_c.translation();
  const double min_cos = std::cos(max_tilt_deg * M_PI / 180.0);
  for (const auto& [id, plane] : map.planes()) {
    if (plane.observations.size() < min_keyframes || !(plane.normal.norm() > 0.5)) continue;
    mapping::FloorPlane f;
    f.normal = plane.normal.normalized();
    f.d = plane.d / plane.normal.norm();
    if (f.height(camera) < 0.0) {  // oriented towards the cameras
      f.normal = -f.normal;
      f.d = -f.d;
    }
    const double below = f.height(camera);  // the camera's height above it
    if (f.normal.dot(up) >= min_cos && below >= 0.2 && below <= 3.0) out.push_back(f);
  }
  return out;
}

mapping::KeyframeDepth dense_keyframe(const PinholeCamera& camera, const cv::Mat& depth,
                                      const SE3& T_w_c, const std::vector<DynamicRegion>& still,
                                      const std::vector<DynamicRegion>& dynamic,
                                      const std::vector<DynamicRegion>& movers,
                                      double depth_margin) {
  mapping::KeyframeDepth kf;
  kf.T_w_c = T_w_c;
  kf.camera = camera;
  kf.camera.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};  // the depth is undistorted
  kf.depth = depth;
  kf.dynamic_mask = region_mask(depth, dynamic, depth_margin);
  kf.mover_mask = region_mask(depth, movers, depth_margin);
  const auto margin = static_cast<float>(depth_margin);
  for (const DynamicRegion& r : still) {
    if (r.track_id < 0) continue;
    const bool banded = r.depth_far > 0.0f;
    kf.still_objects.push_back({r.track_id, r.box,
                                banded ? std::max(0.0f, r.depth_near - margin) : -1.0f,
                                banded ? r.depth_far + margin : -1.0f});
  }
  for (const auto* regions : {&dynamic, &movers})
    for (const DynamicRegion& r : *regions)
      if (r.track_id >= 0) kf.moving_objects.push_back(r.track_id);
  return kf;
}

}  // namespace mcslam::slam
