#pragma once

#include <vector>

#include "mcslam/core/se3.hpp"

namespace mcslam {

/// A pose with its timestamp (seconds). T_w_c maps camera points into the world frame.
struct StampedPose {
  double timestamp = 0.0;
  SE3 T_w_c;
};

/// Poses in increasing timestamp order.
using Trajectory = std::vector<StampedPose>;

}  // namespace mcslam
