#pragma once
// Oriented-box geometry of synthetic scene objects, shared by the dynamic-scene and crowd tests:
// clearance between moving objects and from the camera.

#include <Eigen/Core>
#include <cmath>
#include <vector>

#include "mcslam/synth/scene.hpp"

namespace mcslam::synth::test {

/// An oriented box in the world frame.
struct Obb {
  Eigen::Vector3d centre;
  Eigen::Matrix3d axes;  // columns: the box axes in the world frame
  Eigen::Vector3d half;
};

inline Obb obb_of(const SceneObject& object, double t) {
  const SE3 T = object.pose_at(t);
  return {T.translation(), T.rotation(), object.half_extents};
}

/// Whether two oriented boxes come closer than `margin` along every separating-axis candidate
/// (the 15 axes of the separating axis theorem): false proves a gap of at least `margin`.
inline bool within(const Obb& a, const Obb& b, double margin) {
  std::vector<Eigen::Vector3d> axes;
  for (int i = 0; i < 3; ++i) {
    axes.push_back(a.axes.col(i));
    axes.push_back(b.axes.col(i));
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector3d c = a.axes.col(i).cross(b.axes.col(j));
      if (c.norm() > 1e-9) axes.push_back(c.normalized());
    }
  }
  const Eigen::Vector3d d = b.centre - a.centre;
  for (const Eigen::Vector3d& l : axes) {
    double ra = 0.0, rb = 0.0;
    for (int k = 0; k < 3; ++k) {
      ra += a.half[k] * std::abs(l.dot(a.axes.col(k)));
      rb += b.half[k] * std::abs(l.dot(b.axes.col(k)));
    }
    if (std::abs(l.dot(d)) > ra + rb + margin) return false;
  }
  return true;
}

/// Distance from a point to a solid oriented box (0 inside).
inline double distance_to(const Obb& box, const Eigen::Vector3d& p) {
  const Eigen::Vector3d q = box.axes.transpose() * (p - box.centre);
  return (q.cwiseAbs() - box.half).cwiseMax(0.0).norm();
}

}  // namespace mcslam::synth::test
