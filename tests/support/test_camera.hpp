#pragma once
// The 640x480 pinhole camera the unit tests use (no distortion, bf 40).

#include "mcslam/core/camera.hpp"

namespace mcslam::test {

inline PinholeCamera make_camera(double fx = 525.0, double fy = 525.0, double cx = 319.5,
                                 double cy = 239.5) {
  PinholeCamera c;
  c.fx = fx;
  c.fy = fy;
  c.cx = cx;
  c.cy = cy;
  c.width = 640;
  c.height = 480;
  c.bf = 40.0;
  return c;
}

}  // namespace mcslam::test
