#include "mcslam/optim/plane_residual.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "mcslam/core/se3.hpp"
#include "mcslam/optim/se3_manifold.hpp"
#include "support/manifold_diff.hpp"
#include "support/numeric_diff.hpp"
#include "support/random_geometry.hpp"

namespace mcslam::optim {
namespace {

constexpr double kPi = std::numbers::pi;
using RowJPose = Eigen::Matrix<double, 3, 7, Eigen::RowMajor>;
using RowJPlane = Eigen::Matrix<double, 3, 4, Eigen::RowMajor>;

using test::random_pose;
using test::random_unit;

// n rotated by `angle` about a random axis orthogonal to it.
Eigen::Vector3d tilt(const Eigen::Vector3d& n, double angle, std::mt19937& rng) {
  const Eigen::Vector3d axis = n.cross(random_unit(rng)).normalized();
  return Eigen::AngleAxisd(angle, axis) * n;
}

// The camera-frame plane that a pose sees of a world plane.
void to_camera(const SE3& T_c_w, const Eigen::Vector4d& plane_w, Eigen::Vector3d* n_c,
               double* d_c) {
  *n_c = T_c_w.rotation() * plane_w.head<3>();
  *d_c = plane_w.w() - n_c->dot(T_c_w.translation());
}

Eigen::Vector3d evaluate(const ceres::CostFunction& cost, const double* pose, const double* plane) {
  const double* params[2] = {pose, plane};
  Eigen::Vector3d r;
  EXPECT_TRUE(cost.Evaluate(params, r.data(), nullptr));
  return r;
}

double plane_tolerance(const Eigen::MatrixXd& numeric) { return 1e-5 * (1.0 + numeric.norm()); }

// Analytic ambient and tangent Jacobians of a PlaneError against central differences.
void check_plane_jacobians(const PlaneMeasurement& m, const SE3& T_c_w,
                           const Eigen::Vector4d& plane_w) {
  PlaneError cost(m);
  double pose[7];
  pose_to_block(T_c_w, pose);
  Eigen::Vector4d plane = plane_w;
  RowJPose J_pose;
  RowJPlane J_plane;
  double* jac[2] = {J_pose.data(), J_plane.data()};
  const double* params[2] = {pose, plane.data()};
  Eigen::Vector3d r;
  ASSERT_TRUE(cost.Evaluate(params, r.data(), jac));
  ASSERT_TRUE(r.allFinite());
  ASSERT_TRUE(J_pose.allFinite());
  ASSERT_TRUE(J_plane.allFinite());

  const Eigen::MatrixXd num_pose = test::numeric_jacobian(
      [&](const Eigen::VectorXd& x) {
        return Eigen::VectorXd(evaluate(cost, x.data(), plane.data()));
      },
      Eigen::Map<Eigen::VectorXd>(pose, 7));
  const Eigen::MatrixXd num_plane = test::numeric_jacobian(
      [&](const Eigen::VectorXd& x) { return Eigen::VectorXd(evaluate(cost, pose, x.data())); },
      plane);
  EXPECT_LT((num_pose - Eigen::MatrixXd(J_pose)).norm(), plane_tolerance(num_pose));
  EXPECT_LT((num_plane - Eigen::MatrixXd(J_plane)).norm(), plane_tolerance(num_plane));

  // Tangent Jacobians through both manifolds, as Ceres forms them.
  SE3Manifold se3;
  PlaneManifold plane_manifold;
  Eigen::Matrix<double, 7, 6, Eigen::RowMajor> P_pose;
  Eigen::Matrix<double, 4, 3, Eigen::RowMajor> P_plane;
  se3.PlusJacobian(pose, P_pose.data());
  plane_manifold.PlusJacobian(plane.data(), P_plane.data());
  const Eigen::MatrixXd num_xi = test::numeric_jacobian(
      [&](const Eigen::VectorXd& xi) {
        double moved[7];
        se3.Plus(pose, xi.data(), moved);
        return Eigen::VectorXd(evaluate(cost, moved, plane.data()));
      },
      Eigen::VectorXd::Zero(6));
  const Eigen::MatrixXd num_delta = test::numeric_jacobian(
      [&](const Eigen::VectorXd& delta) {
        double moved[4];
        plane_manifold.Plus(plane.data(), delta.data(), moved);
        return Eigen::VectorXd(evaluate(cost, pose, moved));
      },
      Eigen::VectorXd::Zero(3));
  EXPECT_LT((num_xi - Eigen::MatrixXd(J_pose) * P_pose).norm(), plane_tolerance(num_xi));
  EXPECT_LT((num_delta - Eigen::MatrixXd(J_plane) * P_plane).norm(), plane_tolerance(num_delta));
}

TEST(PlaneParameterisation, SphericalAndWrap) {
  EXPECT_LT((spherical({1.0, 0.0, 0.0}, 2.0) - Eigen::Vector3d(0.0, 0.0, 2.0)).norm(), 1e-15);
  EXPECT_NEAR(spherical({0.0, 1.0, 0.0}, 0.0).x(), kPi / 2, 1e-15);
  EXPECT_NEAR(spherical({0.0, 0.0, 1.0}, 0.0).y(), kPi / 2, 1e-15);
  EXPECT_NEAR(spherical({0.0, 0.0, -1.0}, 0.0).y(), -kPi / 2, 1e-15);
  const Eigen::Vector3d n = Eigen::Vector3d(-0.3, 0.5, 0.6).normalized();
  EXPECT_NEAR(spherical(n, 0.0).y(), std::asin(n.z()), 1e-15);  // equation (1)
  EXPECT_NEAR(spherical(n, 0.0).x(), std::atan2(n.y(), n.x()), 1e-15);
  EXPECT_DOUBLE_EQ(spherical({-1.0, -0.0, 0.0}, 0.0).x(), kPi);  // (-pi, pi]

  EXPECT_NEAR(wrap_angle(1.5 * kPi), -0.5 * kPi, 1e-12);
  EXPECT_NEAR(wrap_angle(-1.5 * kPi), 0.5 * kPi, 1e-12);
  EXPECT_NEAR(wrap_angle(0.1 + 4.0 * kPi), 0.1, 1e-12);
  EXPECT_DOUBLE_EQ(wrap_angle(kPi), kPi);
  EXPECT_DOUBLE_EQ(wrap_angle(-kPi), kPi);
  EXPECT_DOUBLE_EQ(wrap_angle(0.25), 0.25);
}

TEST(PlaneParameterisation, ChartRotationTakesNormalToX) {
  std::mt19937 rng(3);
  std::vector<Eigen::Vector3d> normals = {Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitZ(),
                                          Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitY()};
  for (int i = 0; i < 20; ++i) normals.push_back(random_unit(rng));
  for (const auto& n : normals) {
    const Eigen::Matrix3d R = chart_rotation(n);
    EXPECT_LT((R * R.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
    EXPECT_LT((R * n - Eigen::Vector3d::UnitX()).norm(), 1e-12);
    EXPECT_EQ(R, chart_rotation(n));  // deterministic
  }
}

TEST(PlaneManifold, PlusMinusRoundTripAndUnitNormal) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.8, 0.8), d(-3.0, 3.0);
  PlaneManifold manifold;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d n = i == 0 ? Eigen::Vector3d::UnitZ() : random_unit(rng);
    const Eigen::Vector4d x(n.x(), n.y(), n.z(), d(rng));
    const Eigen::Vector3d delta(u(rng), u(rng), u(rng));
    Eigen::Vector4d y;
    ASSERT_TRUE(manifold.Plus(x.data(), delta.data(), y.data()));
    EXPECT_NEAR(y.head<3>().norm(), 1.0, 1e-14);
    // The rotation angle is |(delta0, delta1)|.
    EXPECT_NEAR(std::atan2(n.cross(y.head<3>()).norm(), n.dot(y.head<3>())), delta.head<2>().norm(),
                1e-12);
    Eigen::Vector3d back;
    ASSERT_TRUE(manifold.Minus(y.data(), x.data(), back.data()));
    EXPECT_LT((back - delta).norm(), 1e-10) << i;
    Eigen::Vector4d again;
    ASSERT_TRUE(manifold.Plus(x.data(), back.data(), again.data()));
    EXPECT_LT((again - y).norm(), 1e-12);
    Eigen::Vector3d zero;
    ASSERT_TRUE(manifold.Minus(x.data(), x.data(), zero.data()));
    EXPECT_LT(zero.norm(), 1e-15);
  }
}

TEST(PlaneManifold, JacobiansMatchNumeric) {
  std::mt19937 rng(9);
  PlaneManifold manifold;
  for (int i = 0; i < 10; ++i) {
    const Eigen::Vector3d n = i == 0 ? -Eigen::Vector3d::UnitZ() : random_unit(rng);
    const Eigen::Vector4d x(n.x(), n.y(), n.z(), 1.5);
    Eigen::Matrix<double, 4, 3, Eigen::RowMajor> P;
    Eigen::Matrix<double, 3, 4, Eigen::RowMajor> M;
    ASSERT_TRUE(manifold.PlusJacobian(x.data(), P.data()));
    ASSERT_TRUE(manifold.MinusJacobian(x.data(), M.data()));
    const Eigen::MatrixXd num_plus = test::numeric_plus_jacobian(manifold, x.data());
    // d Minus(y, x) / d y at y = x, perturbing the 4 raw doubles of y.
    const Eigen::MatrixXd num_minus = test::numeric_minus_jacobian(manifold, x.data());
    EXPECT_LT((num_plus - Eigen::MatrixXd(P)).norm(), 1e-8) << i;
    EXPECT_LT((num_minus - Eigen::MatrixXd(M)).norm(), 1e-6) << i;
    EXPECT_LT((M * P - Eigen::Matrix3d::Identity()).norm(), 1e-12);
    EXPECT_LT((P.topRows<3>().transpose() * n).norm(), 1e-12);  // tangent to the sphere
  }
}

TEST(PlaneError, JacobiansMatchNumericAtRandomPoses) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> d(-3.0, 3.0), off(-0.2, 0.2);
  for (int trial = 0; trial < 8; ++trial) {
    const SE3 T_c_w = random_pose(rng);
    const Eigen::Vector3d n_w = random_unit(rng);
    const Eigen::Vector4d plane_w(n_w.x(), n_w.y(), n_w.z(), d(rng));
    Eigen::Vector3d n_c;
    double d_c;
    to_camera(T_c_w, plane_w, &n_c, &d_c);
    PlaneMeasurement m;
    m.normal = tilt(n_c, 0.1, rng);
    m.d = d_c + off(rng);
    m.angle_information = 400.0;
    m.distance_information = 100.0;
    SCOPED_TRACE(trial);
    check_plane_jacobians(m, T_c_w, plane_w);
  }
}

TEST(PlaneError, ZeroAtTruthSignAndChi2) {
  std::mt19937 rng(17);
  const SE3 T_c_w = random_pose(rng);
  const Eigen::Vector3d n_w = random_unit(rng);
  const Eigen::Vector4d plane_w(n_w.x(), n_w.y(), n_w.z(), 2.0);
  Eigen::Vector3d n_c;
  double d_c;
  to_camera(T_c_w, plane_w, &n_c, &d_c);
  // The plane equation holds in both frames.
  const Eigen::Vector3d p_w = -2.0 * n_w + n_w.cross(Eigen::Vector3d::UnitX());
  EXPECT_NEAR(n_c.dot(T_c_w * p_w) + d_c, 0.0, 1e-12);

  PlaneMeasurement m;
  m.normal = n_c;
  m.d = d_c;
  m.angle_information = 4.0;
  m.distance_information = 25.0;
  double pose[7];
  pose_to_block(T_c_w, pose);
  EXPECT_LT(evaluate(PlaneError(m), pose, plane_w.data()).norm(), 1e-12);
  EXPECT_NEAR(plane_chi2(m, n_c, d_c), 0.0, 1e-20);

  // Predicted minus observed: an observation 0.1 m nearer gives +0.1, whitened by 5.
  m.d = d_c - 0.1;
  const Eigen::Vector3d r = evaluate(PlaneError(m), pose, plane_w.data());
  EXPECT_NEAR(r.z(), 0.5, 1e-12);
  EXPECT_NEAR(plane_error(m, n_c, d_c).z(), 0.1, 1e-12);

  // plane_chi2 is the whitened squared norm of the residual.
  m.normal = tilt(n_c, 0.05, rng);
  const Eigen::Vector3d r2 = evaluate(PlaneError(m), pose, plane_w.data());
  const Eigen::Vector3d e = plane_error(m, n_c, d_c);
  EXPECT_NEAR(r2.squaredNorm(), plane_chi2(m, n_c, d_c), 1e-12);
  EXPECT_LT((r2 - Eigen::Vector3d(2.0 * e.x(), 2.0 * e.y(), 5.0 * e.z())).norm(), 1e-12);
  EXPECT_NEAR(e.head<2>().norm(), 0.05, 1e-4);
}

TEST(PoseOnlyPlaneError, MatchesFullResidualAndNumeric) {
  std::mt19937 rng(19);
  for (int trial = 0; trial < 4; ++trial) {
    const SE3 T_c_w = random_pose(rng);
    const Eigen::Vector3d n_w = random_unit(rng);
    const Eigen::Vector4d plane_w(n_w.x(), n_w.y(), n_w.z(), -1.2);
    Eigen::Vector3d n_c;
    double d_c;
    to_camera(T_c_w, plane_w, &n_c, &d_c);
    PlaneMeasurement m;
    m.normal = tilt(n_c, 0.08, rng);
    m.d = d_c + 0.05;
    m.angle_information = 100.0;
    PlaneError full(m);
    PoseOnlyPlaneError pose_only(m, plane_w);
    double pose[7];
    pose_to_block(T_c_w, pose);
    RowJPose J_full, J_pose_only;
    RowJPlane J_plane;
    double* jac_full[2] = {J_full.data(), J_plane.data()};
    double* jac_pose[1] = {J_pose_only.data()};
    const double* params_full[2] = {pose, plane_w.data()};
    const double* params_pose[1] = {pose};
    Eigen::Vector3d r_full, r_pose;
    ASSERT_TRUE(full.Evaluate(params_full, r_full.data(), jac_full));
    ASSERT_TRUE(pose_only.Evaluate(params_pose, r_pose.data(), jac_pose));
    EXPECT_LT((r_full - r_pose).norm(), 1e-14);
    EXPECT_LT((J_full - J_pose_only).norm(), 1e-14);
    const Eigen::MatrixXd num = test::numeric_jacobian(
        [&](const Eigen::VectorXd& x) {
          const double* p[1] = {x.data()};
          Eigen::Vector3d out;
          pose_only.Evaluate(p, out.data(), nullptr);
          return Eigen::VectorXd(out);
        },
        Eigen::Map<Eigen::VectorXd>(pose, 7));
    EXPECT_LT((num - Eigen::MatrixXd(J_pose_only)).norm(), plane_tolerance(num)) << trial;
  }
}

// Observed phi just below +pi, predicted just across at -pi: a small residual, not ~2 pi.
TEST(PlaneError, AzimuthWrapAround) {
  const double theta = 0.3;
  const auto direction = [&](double phi) {
    return Eigen::Vector3d(std::cos(theta) * std::cos(phi), std::cos(theta) * std::sin(phi),
                           std::sin(theta));
  };
  PlaneMeasurement m;
  m.normal = direction(kPi - 0.01);
  m.d = 1.0;
  const Eigen::Vector3d n_pred = direction(-kPi + 0.01);
  const double angle = std::acos(m.normal.dot(n_pred));
  const Eigen::Vector3d e = plane_error(m, n_pred, 1.0);
  EXPECT_NEAR(e.head<2>().norm(), angle, 1e-6);
  EXPECT_LT(e.head<2>().norm(), 0.02);
  // The raw paper parameterisation needs the wrap for the same answer.
  const Eigen::Vector3d raw = spherical(n_pred, 1.0) - spherical(m.normal, 1.0);
  EXPECT_NEAR(std::abs(raw.x()), 2.0 * kPi - 0.02, 1e-9);
  EXPECT_NEAR(wrap_angle(raw.x()), 0.02, 1e-9);

  // A flipped normal is as far as it gets, but stays finite and within (-pi, pi].
  const Eigen::Vector3d flipped = plane_error(m, -m.normal, 1.0);
  EXPECT_TRUE(flipped.allFinite());
  EXPECT_LE(std::abs(flipped.x()), kPi);
}

// A wall facing the camera: the observed normal is a pole of equation (1), where phi is undefined.
TEST(PlaneError, FiniteAndProportionalAtTheElevationPoles) {
  std::mt19937 rng(23);
  for (const double sign : {1.0, -1.0}) {
    const Eigen::Vector3d n_obs = sign * Eigen::Vector3d::UnitZ();
    PlaneMeasurement m;
    m.normal = n_obs;
    m.d = 2.0;
    m.angle_information = 1.0;
    m.distance_information = 1.0;
    for (const double angle : {1e-4, 1e-3, 1e-2}) {
      const Eigen::Vector3d n_pred = tilt(n_obs, angle, rng);
      const Eigen::Vector3d e = plane_error(m, n_pred, 2.0);
      ASSERT_TRUE(e.allFinite());
      EXPECT_NEAR(e.head<2>().norm(), angle, 1e-3 * angle) << sign << " " << angle;
      EXPECT_NEAR(e.z(), 0.0, 1e-15);
    }
    // Jacobians at a pose that sees the world plane as the observed wall (exactly, then nearly).
    for (const double angle : {0.0, 0.02}) {
      const SE3 T_c_w = random_pose(rng);
      const Eigen::Vector3d n_c = tilt(n_obs, angle, rng);
      const Eigen::Vector3d n_w = T_c_w.rotation().transpose() * n_c;
      const double d_w = 2.0 + n_c.dot(T_c_w.translation());
      const Eigen::Vector4d plane_w(n_w.x(), n_w.y(), n_w.z(), d_w);
      double pose[7];
      pose_to_block(T_c_w, pose);
      const Eigen::Vector3d r = evaluate(PlaneError(m), pose, plane_w.data());
      EXPECT_NEAR(r.head<2>().norm(), angle, 1e-6);
      EXPECT_NEAR(r.z(), 0.0, 1e-12);
      SCOPED_TRACE(angle);
      check_plane_jacobians(m, T_c_w, plane_w);
    }
  }
}

// Away from the poles the chart residual and the paper's raw q difference agree to first order up
// to a rotation of the (phi, theta) plane: with the raw azimuth scaled by cos(theta) (the metric
// of the sphere), both preserve lengths (the angle between normals) and inner products.
TEST(PlaneError, AgreesWithRawParameterisationAwayFromPoles) {
  std::mt19937 rng(29);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::Vector3d n_obs = random_unit(rng);
    if (std::abs(n_obs.z()) > 0.8) continue;  // away from the raw singularities
    PlaneMeasurement m;
    m.normal = n_obs;
    m.d = 1.0;
    const Eigen::Vector3d q_obs = spherical(n_obs, 1.0);
    const auto raw_scaled = [&](const Eigen::Vector3d& n) {
      const Eigen::Vector3d dq = spherical(n, 1.0) - q_obs;
      return Eigen::Vector2d(std::cos(q_obs.y()) * wrap_angle(dq.x()), dq.y());
    };
    const double angle = 1e-3;
    const Eigen::Vector3d n1 = tilt(n_obs, angle, rng), n2 = tilt(n_obs, angle, rng);
    const Eigen::Vector2d c1 = plane_error(m, n1, 1.0).head<2>();
    const Eigen::Vector2d c2 = plane_error(m, n2, 1.0).head<2>();
    const Eigen::Vector2d r1 = raw_scaled(n1), r2 = raw_scaled(n2);
    EXPECT_NEAR(c1.norm(), angle, 1e-6 * angle);
    EXPECT_NEAR(r1.norm(), angle, 1e-2 * angle);
    EXPECT_NEAR(c1.dot(c2), r1.dot(r2), 1e-2 * angle * angle) << trial;
    // Same orientation of the plane: the map between them is a rotation, not a reflection.
    const double cross_c = c1.x() * c2.y() - c1.y() * c2.x();
    const double cross_r = r1.x() * r2.y() - r1.y() * r2.x();
    EXPECT_NEAR(cross_c, cross_r, 1e-2 * angle * angle) << trial;
  }
}

}  // namespace
}  // namespace mcslam::optim
