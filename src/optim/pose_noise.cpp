#include "mcslam/optim/pose_noise.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

namespace mcslam::optim {

namespace {
/// Chi-square's median with 6 degrees of freedom.
constexpr double kChi2MedianDof6 = 5.348;
}  // namespace

std::optional<Eigen::Vector4d> third_difference_coefficients(const Eigen::Vector4d& t) {
  const double h = (t[3] - t[0]) / 3.0;
  if (!(h > 0.0)) return std::nullopt;
  Eigen::Vector4d a;
  for (int i = 0; i < 4; ++i) {
    double p = 1.0;
    for (int j = 0; j < 4; ++j)
      if (j != i) p *= (t[i] - t[j]) / h;
    if (!(std::abs(p) > 1e-12)) return std::nullopt;  // two equal timestamps
    a[i] = 6.0 / p;
  }
  return a;
}

PoseNoiseEstimate::PoseNoiseEstimate(double window) : window_(window) {}

void PoseNoiseEstimate::add(double timestamp, const Eigen::Matrix3d& R_c_w,
                            const Eigen::Vector3d& c, const Matrix6d& information) {
  if (!information.allFinite() || !R_c_w.allFinite() || !c.allFinite()) {
    break_sequence();
    return;
  }
  poses_.push_back({timestamp, R_c_w, c, information});
  if (poses_.size() > 4) poses_.pop_front();
  while (!values_.empty() && values_.front().first < timestamp - window_) values_.pop_front();
  if (poses_.size() < 4) return;
  const auto a = third_difference_coefficients(
      {poses_[0].timestamp, poses_[1].timestamp, poses_[2].timestamp, poses_[3].timestamp});
  if (!a) {
    break_sequence();
    return;
  }
  // The rotations as small turns from the third pose's (left, camera frame), as the filter
  // measures them; the information of that pose stands for the four (they change slowly).
  const Pose& mid = poses_[2];
  Vector6d d = Vector6d::Zero();
  for (int i = 0; i < 4; ++i) {
    d.head<3>() += (*a)[i] * poses_[static_cast<std::size_t>(i)].c;
    d.tail<3>() += (*a)[i] * so3_log(Eigen::Quaterniond(poses_[static_cast<std::size_t>(i)].R_c_w *
                                                        mid.R_c_w.transpose()));
  }
  const double normalised = d.dot(mid.information * d) / a->squaredNorm();
  if (std::isfinite(normalised)) values_.emplace_back(timestamp, normalised);
}

void PoseNoiseEstimate::move_world(const SE3& W) {
  const Eigen::Matrix3d R_W = W.rotation();
  Matrix6d J = Matrix6d::Identity();  // d(centre) turns with the world; the camera's turn stays
  J.block<3, 3>(0, 0) = R_W;
  for (Pose& p : poses_) {
    p.c = W * p.c;
    p.R_c_w = p.R_c_w * R_W.transpose();
    p.information = J * p.information * J.transpose();
  }
}

double PoseNoiseEstimate::variance_factor() const {
  if (values_.size() < kMinValues) return 1.0;
  std::vector<double> v;
  v.reserve(values_.size());
  for (const auto& [t, x] : values_) v.push_back(x);
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid / kChi2MedianDof6;
}

}  // namespace mcslam::optim
