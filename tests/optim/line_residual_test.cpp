#include "mcslam/optim/line_residual.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "mcslam/optim/se3_manifold.hpp"
#include "support/manifold_diff.hpp"
#include "support/numeric_diff.hpp"
#include "support/random_geometry.hpp"
#include "support/test_camera.hpp"

namespace mcslam::optim {
namespace {

using RowJ7 = Eigen::Matrix<double, 2, 7, Eigen::RowMajor>;
using RowJ3 = Eigen::Matrix<double, 2, 3, Eigen::RowMajor>;

SE3 spread_pose(std::mt19937& rng) { return test::random_pose(rng, 0.5); }

// The normalised image line through two pixels.
Eigen::Vector3d line_through(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector3d l = a.homogeneous().cross(b.homogeneous());
  return l / l.head<2>().norm();
}

struct LineCase {
  SE3 T_c_w;
  Eigen::Vector3d start_w, end_w;
  LineMeasurement m;
};

// Endpoints in front of the camera, observed as a line a few pixels off their projections.
LineCase random_case(const PinholeCamera& cam, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(50.0, 590.0), v(50.0, 430.0), z(1.0, 4.0),
      off(-5.0, 5.0);
  LineCase c;
  c.T_c_w = spread_pose(rng);
  const Eigen::Vector3d s_c = cam.unproject({u(rng), v(rng)}, z(rng));
  const Eigen::Vector3d e_c = cam.unproject({u(rng), v(rng)}, z(rng));
  c.start_w = c.T_c_w.inverse() * s_c;
  c.end_w = c.T_c_w.inverse() * e_c;
  c.m.coefficients = line_through(cam.project(s_c) + Eigen::Vector2d(off(rng), off(rng)),
                                  cam.project(e_c) + Eigen::Vector2d(off(rng), off(rng)));
  c.m.information = 1.0 / 2.25;
  return c;
}

double tolerance(const Eigen::MatrixXd& numeric) { return 1e-5 * (1.0 + numeric.norm()); }

TEST(LineReprojectionError, JacobiansMatchNumeric) {
  std::mt19937 rng(7);
  const PinholeCamera cam = test::make_camera(520.0, 515.0, 320.0, 240.0);
  for (int trial = 0; trial < 6; ++trial) {
    const LineCase c = random_case(cam, rng);
    LineReprojectionError cost(cam, c.m);
    double pose[7];
    pose_to_block(c.T_c_w, pose);
    Eigen::Vector3d start = c.start_w, end = c.end_w;
    const auto eval = [&](const double* p, const double* s, const double* e) {
      const double* params[3] = {p, s, e};
      Eigen::Vector2d r;
      EXPECT_TRUE(cost.Evaluate(params, r.data(), nullptr));
      return Eigen::VectorXd(r);
    };
    RowJ7 J_pose;
    RowJ3 J_start, J_end;
    double* jac[3] = {J_pose.data(), J_start.data(), J_end.data()};
    const double* params[3] = {pose, start.data(), end.data()};
    Eigen::Vector2d r;
    ASSERT_TRUE(cost.Evaluate(params, r.data(), jac));
    EXPECT_LT((Eigen::VectorXd(r) - eval(pose, start.data(), end.data())).norm(), 1e-12);

    // Ambient Jacobians against differences of the raw doubles.
    const Eigen::MatrixXd num_pose = test::numeric_jacobian(
        [&](const Eigen::VectorXd& x) { return eval(x.data(), start.data(), end.data()); },
        Eigen::Map<Eigen::VectorXd>(pose, 7));
    const Eigen::MatrixXd num_start = test::numeric_jacobian(
        [&](const Eigen::VectorXd& x) { return eval(pose, x.data(), end.data()); }, start);
    const Eigen::MatrixXd num_end = test::numeric_jacobian(
        [&](const Eigen::VectorXd& x) { return eval(pose, start.data(), x.data()); }, end);
    EXPECT_LT((num_pose - Eigen::MatrixXd(J_pose)).norm(), tolerance(num_pose)) << trial;
    EXPECT_LT((num_start - Eigen::MatrixXd(J_start)).norm(), tolerance(num_start)) << trial;
    EXPECT_LT((num_end - Eigen::MatrixXd(J_end)).norm(), tolerance(num_end)) << trial;
    // Row k depends on endpoint k only.
    EXPECT_EQ(J_start.row(1).norm(), 0.0);
    EXPECT_EQ(J_end.row(0).norm(), 0.0);

    // Through the SE3 manifold: differences of exp(xi) * T.
    SE3Manifold manifold;
    Eigen::Matrix<double, 7, 6, Eigen::RowMajor> P;
    manifold.PlusJacobian(pose, P.data());
    const Eigen::MatrixXd num_tangent = test::numeric_jacobian(
        [&](const Eigen::VectorXd& xi) {
          double moved[7];
          manifold.Plus(pose, xi.data(), moved);
          return eval(moved, start.data(), end.data());
        },
        Eigen::VectorXd::Zero(6));
    EXPECT_LT((num_tangent - Eigen::MatrixXd(J_pose) * P).norm(), tolerance(num_tangent)) << trial;
  }
}

TEST(LineSegmentError, OneSixVectorBlockMatchesTheTwoEndpointBlocksAndNumeric) {
  std::mt19937 rng(13);
  const PinholeCamera cam = test::make_camera(520.0, 515.0, 320.0, 240.0);
  for (int trial = 0; trial < 6; ++trial) {
    const LineCase c = random_case(cam, rng);
    LineReprojectionError two_blocks(cam, c.m);
    LineSegmentError one_block(cam, c.m);
    double pose[7];
    pose_to_block(c.T_c_w, pose);
    Eigen::Matrix<double, 6, 1> segment;
    segment << c.start_w, c.end_w;

    RowJ7 J_pose_two, J_pose_one;
    RowJ3 J_start, J_end;
    Eigen::Matrix<double, 2, 6, Eigen::RowMajor> J_segment;
    const double* params_two[3] = {pose, c.start_w.data(), c.end_w.data()};
    const double* params_one[2] = {pose, segment.data()};
    double* jac_two[3] = {J_pose_two.data(), J_start.data(), J_end.data()};
    double* jac_one[2] = {J_pose_one.data(), J_segment.data()};
    Eigen::Vector2d r_two, r_one;
    ASSERT_TRUE(two_blocks.Evaluate(params_two, r_two.data(), jac_two));
    ASSERT_TRUE(one_block.Evaluate(params_one, r_one.data(), jac_one));
    EXPECT_EQ((r_two - r_one).norm(), 0.0);
    EXPECT_EQ((J_pose_two - J_pose_one).norm(), 0.0);
    EXPECT_EQ((J_segment.leftCols<3>() - J_start).norm(), 0.0);
    EXPECT_EQ((J_segment.rightCols<3>() - J_end).norm(), 0.0);

    // Only the segment's Jacobian asked for (the pose held constant by Ceres).
    Eigen::Matrix<double, 2, 6, Eigen::RowMajor> J_segment_only;
    double* jac_segment_only[2] = {nullptr, J_segment_only.data()};
    ASSERT_TRUE(one_block.Evaluate(params_one, r_one.data(), jac_segment_only));
    EXPECT_EQ((J_segment_only - J_segment).norm(), 0.0);

    const Eigen::MatrixXd numeric = test::numeric_jacobian(
        [&](const Eigen::VectorXd& x) {
          const double* p[2] = {pose, x.data()};
          Eigen::Vector2d out;
          EXPECT_TRUE(one_block.Evaluate(p, out.data(), nullptr));
          return Eigen::VectorXd(out);
        },
        Eigen::VectorXd(segment));
    EXPECT_LT((numeric - Eigen::MatrixXd(J_segment)).norm(), tolerance(numeric)) << trial;
  }
}

TEST(SegmentManifold, MovesEndpointsOnlyAcrossTheLineAndRoundTrips) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> coord(-2.0, 2.0), step(-0.3, 0.3);
  SegmentManifold manifold;
  for (int trial = 0; trial < 30; ++trial) {
    Eigen::Matrix<double, 6, 1> x;
    for (int i = 0; i < 6; ++i) x[i] = coord(rng);
    if (trial == 0) x << 0.0, 0.0, 1.0, 0.0, 0.0, 3.0;  // along an axis
    const Eigen::Vector3d d = (x.tail<3>() - x.head<3>()).normalized();
    Eigen::Vector4d delta;
    for (int i = 0; i < 4; ++i) delta[i] = step(rng);
    Eigen::Matrix<double, 6, 1> y;
    ASSERT_TRUE(manifold.Plus(x.data(), delta.data(), y.data()));
    // Each endpoint moves by |its two coordinates|, across the line.
    for (int k = 0; k < 2; ++k) {
      const Eigen::Vector3d moved = y.segment<3>(3 * k) - x.segment<3>(3 * k);
      EXPECT_NEAR(moved.dot(d), 0.0, 1e-14) << trial;
      EXPECT_NEAR(moved.norm(), delta.segment<2>(2 * k).norm(), 1e-14) << trial;
    }
    Eigen::Vector4d back;
    ASSERT_TRUE(manifold.Minus(y.data(), x.data(), back.data()));
    EXPECT_LT((back - delta).norm(), 1e-14) << trial;
    Eigen::Vector4d zero;
    ASSERT_TRUE(manifold.Minus(x.data(), x.data(), zero.data()));
    EXPECT_EQ(zero.norm(), 0.0);
  }
  // A segment of zero length still gets a valid chart.
  const Eigen::Matrix<double, 6, 1> point = Eigen::Matrix<double, 6, 1>::Constant(0.5);
  const Eigen::Vector4d delta(0.1, -0.2, 0.3, 0.0);
  Eigen::Matrix<double, 6, 1> moved;
  ASSERT_TRUE(manifold.Plus(point.data(), delta.data(), moved.data()));
  EXPECT_TRUE(moved.allFinite());
  EXPECT_NEAR((moved - point).head<3>().norm(), delta.head<2>().norm(), 1e-14);
}

TEST(SegmentManifold, JacobiansMatchNumericAndRemoveTheSlidingOfTheEndpoints) {
  std::mt19937 rng(22);
  const PinholeCamera cam = test::make_camera(520.0, 515.0, 320.0, 240.0);
  SegmentManifold manifold;
  for (int trial = 0; trial < 6; ++trial) {
    const LineCase c = random_case(cam, rng);
    Eigen::Matrix<double, 6, 1> x;
    x << c.start_w, c.end_w;
    Eigen::Matrix<double, 6, 4, Eigen::RowMajor> P;
    Eigen::Matrix<double, 4, 6, Eigen::RowMajor> M;
    ASSERT_TRUE(manifold.PlusJacobian(x.data(), P.data()));
    ASSERT_TRUE(manifold.MinusJacobian(x.data(), M.data()));
    const Eigen::MatrixXd num_plus = test::numeric_plus_jacobian(manifold, x.data());
    const Eigen::MatrixXd num_minus = test::numeric_minus_jacobian(manifold, x.data());
    EXPECT_LT((num_plus - Eigen::MatrixXd(P)).norm(), 1e-8) << trial;
    EXPECT_LT((num_minus - Eigen::MatrixXd(M)).norm(), 1e-8) << trial;
    EXPECT_LT((M * P - Eigen::Matrix4d::Identity()).norm(), 1e-14) << trial;

    // Where the observed line is the projection of the 3D line, sliding an endpoint along the
    // line leaves residual (7) unchanged: in the 6 raw coordinates the segment's Jacobian has
    // those two null directions, and the chart's four columns are orthogonal to them. (With a
    // noisy observation the slide changes the residual only through the angle between the
    // observed and the projected line: it carries no information about the segment's extent.)
    LineMeasurement exact = c.m;
    exact.coefficients =
        line_through(cam.project(c.T_c_w * c.start_w), cam.project(c.T_c_w * c.end_w));
    LineSegmentError cost(cam, exact);
    double pose[7];
    pose_to_block(c.T_c_w, pose);
    Eigen::Matrix<double, 2, 7, Eigen::RowMajor> J_pose;
    Eigen::Matrix<double, 2, 6, Eigen::RowMajor> J_segment;
    const double* params[2] = {pose, x.data()};
    double* jac[2] = {J_pose.data(), J_segment.data()};
    Eigen::Vector2d r;
    ASSERT_TRUE(cost.Evaluate(params, r.data(), jac));
    const Eigen::Vector3d d = (c.end_w - c.start_w).normalized();
    Eigen::Matrix<double, 6, 2> slide = Eigen::Matrix<double, 6, 2>::Zero();
    slide.block<3, 1>(0, 0) = d;
    slide.block<3, 1>(3, 1) = d;
    EXPECT_LT((J_segment * slide).norm(), 1e-9 * J_segment.norm()) << trial;
    EXPECT_LT((P.transpose() * slide).norm(), 1e-14) << trial;
    // The residual's Jacobian in the chart keeps what the raw one constrains: each row (one
    // endpoint) is as large as before.
    const Eigen::Matrix<double, 2, 4> J_chart = J_segment * P;
    for (int k = 0; k < 2; ++k)
      EXPECT_NEAR(J_chart.row(k).norm(), J_segment.row(k).norm(), 1e-9 * J_segment.norm());
  }
}

TEST(PoseOnlyLineError, MatchesFullResidualAndNumeric) {
  std::mt19937 rng(11);
  const PinholeCamera cam = test::make_camera();
  for (int trial = 0; trial < 4; ++trial) {
    const LineCase c = random_case(cam, rng);
    LineReprojectionError full(cam, c.m);
    PoseOnlyLineError pose_only(cam, c.m, c.start_w, c.end_w);
    double pose[7];
    pose_to_block(c.T_c_w, pose);
    const double* params_full[3] = {pose, c.start_w.data(), c.end_w.data()};
    const double* params_pose[1] = {pose};
    RowJ7 J_full, J_pose_only;
    RowJ3 J_start, J_end;
    double* jac_full[3] = {J_full.data(), J_start.data(), J_end.data()};
    double* jac_pose[1] = {J_pose_only.data()};
    Eigen::Vector2d r_full, r_pose;
    ASSERT_TRUE(full.Evaluate(params_full, r_full.data(), jac_full));
    ASSERT_TRUE(pose_only.Evaluate(params_pose, r_pose.data(), jac_pose));
    EXPECT_LT((r_full - r_pose).norm(), 1e-12);
    EXPECT_LT((J_full - J_pose_only).norm(), 1e-12);

    const Eigen::MatrixXd num = test::numeric_jacobian(
        [&](const Eigen::VectorXd& x) {
          const double* p[1] = {x.data()};
          Eigen::Vector2d out;
          pose_only.Evaluate(p, out.data(), nullptr);
          return Eigen::VectorXd(out);
        },
        Eigen::Map<Eigen::VectorXd>(pose, 7));
    EXPECT_LT((num - Eigen::MatrixXd(J_pose_only)).norm(), tolerance(num)) << trial;
  }
}

TEST(LineReprojectionError, SignedPixelDistancesAndChi2) {
  const PinholeCamera cam = test::make_camera();
  const SE3 T_c_w = SE3::exp((Vector6d() << 0.1, 0.2, -0.1, 0.05, -0.1, 0.2).finished());
  const Eigen::Vector3d s_c(-0.4, 0.1, 2.0), e_c(0.5, -0.2, 3.0);
  LineMeasurement m;
  m.coefficients = line_through(cam.project(s_c), cam.project(e_c));
  m.information = 0.25;
  double pose[7];
  pose_to_block(T_c_w, pose);
  const Eigen::Vector3d s_w = T_c_w.inverse() * s_c, e_w = T_c_w.inverse() * e_c;
  const double* params[3] = {pose, s_w.data(), e_w.data()};
  Eigen::Vector2d r;
  ASSERT_TRUE(LineReprojectionError(cam, m).Evaluate(params, r.data(), nullptr));
  EXPECT_LT(r.norm(), 1e-9);
  EXPECT_NEAR(line_chi2(cam, m, s_c, e_c), 0.0, 1e-12);

  // Moving the observed line 2 px along its normal: each endpoint is 2 px off, whitened to 1.
  m.coefficients.z() -= 2.0;
  ASSERT_TRUE(LineReprojectionError(cam, m).Evaluate(params, r.data(), nullptr));
  EXPECT_NEAR(r[0], -1.0, 1e-9);
  EXPECT_NEAR(r[1], -1.0, 1e-9);
  EXPECT_NEAR(line_chi2(cam, m, s_c, e_c), 8.0, 1e-9);  // unwhitened, pixels^2
}

TEST(LineReprojectionError, BehindCameraStaysFinite) {
  const PinholeCamera cam = test::make_camera();
  LineMeasurement m;
  m.coefficients = line_through({100.0, 100.0}, {500.0, 300.0});
  LineReprojectionError cost(cam, m);
  double pose[7];
  pose_to_block(SE3(), pose);
  for (const double z : {0.0, -1.0, 1e-9}) {
    const Eigen::Vector3d s_w(0.2, 0.1, z), e_w(-0.3, 0.2, 2.0);
    const double* params[3] = {pose, s_w.data(), e_w.data()};
    RowJ7 J_pose;
    RowJ3 J_start, J_end;
    double* jac[3] = {J_pose.data(), J_start.data(), J_end.data()};
    Eigen::Vector2d r;
    ASSERT_TRUE(cost.Evaluate(params, r.data(), jac));
    EXPECT_TRUE(r.allFinite());
    EXPECT_GT(r[0], 1e3);  // large enough to be an outlier
    EXPECT_TRUE(J_pose.allFinite());
    EXPECT_EQ(J_pose.row(0).norm(), 0.0);
    EXPECT_GT(J_pose.row(1).norm(), 0.0);  // the visible endpoint still constrains the pose
    EXPECT_EQ(J_start.norm(), 0.0);
    EXPECT_TRUE(std::isinf(line_chi2(cam, m, s_w, e_w)));
    EXPECT_TRUE(std::isinf(line_chi2(cam, m, e_w, s_w)));
  }
}

}  // namespace
}  // namespace mcslam::optim
