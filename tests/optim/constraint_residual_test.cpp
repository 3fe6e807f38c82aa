#include "mcslam/optim/constraint_residual.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include "mcslam/optim/pose_optimizer.hpp"
#include "mcslam/optim/se3_manifold.hpp"
#include "support/numeric_diff.hpp"
#include "support/random_geometry.hpp"
#include "support/test_camera.hpp"

namespace mcslam::optim {
namespace {

using RowJPose1 = Eigen::Matrix<double, 1, 7, Eigen::RowMajor>;

using test::random_pose;
using test::random_unit;

// A unit vector orthogonal to n.
Eigen::Vector3d random_orthogonal(const Eigen::Vector3d& n, std::mt19937& rng) {
  return n.cross(random_unit(rng)).normalized();
}

// A random motion of an object sliding on a plane with normal n (world frame): a rotation about
// n through a pivot and a translation orthogonal to n. It keeps n . p of every point.
SE3 random_slide(const Eigen::Vector3d& n, std::mt19937& rng) {
  std::uniform_real_distribution<double> angle(-1.0, 1.0), shift(-0.5, 0.5), pivot(-2.0, 2.0);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(angle(rng), n).toRotationMatrix();
  const Eigen::Vector3d c(pivot(rng), pivot(rng), pivot(rng));
  const Eigen::Vector3d along = shift(rng) * random_orthogonal(n, rng);
  return SE3(R, c - R * c + along);
}

// A unit direction at `elevation` (rad) to the plane with normal n: sin(elevation) = s . n.
Eigen::Vector3d direction_at_elevation(const Eigen::Vector3d& n, double elevation,
                                       std::mt19937& rng) {
  return std::cos(elevation) * random_orthogonal(n, rng) + std::sin(elevation) * n;
}

double evaluate(const ceres::CostFunction& cost, const double* pose, RowJPose1* J = nullptr) {
  const double* params[1] = {pose};
  double* jac[1] = {J != nullptr ? J->data() : nullptr};
  double r = 0.0;
  EXPECT_TRUE(cost.Evaluate(params, &r, J != nullptr ? jac : nullptr));
  return r;
}

double tight_tolerance(const Eigen::MatrixXd& numeric) { return 1e-6 * (1.0 + numeric.norm()); }

// Ambient (7 raw doubles) and tangent (through SE3Manifold, as Ceres forms it) Jacobians of a
// pose-only cost against central differences.
void check_pose_jacobian(const ceres::CostFunction& cost, const SE3& T_c_w) {
  double pose[7];
  pose_to_block(T_c_w, pose);
  RowJPose1 J;
  const double r = evaluate(cost, pose, &J);
  ASSERT_TRUE(std::isfinite(r));
  ASSERT_TRUE(J.allFinite());
  const auto f = [&](const double* x) {
    Eigen::VectorXd out(1);
    out[0] = evaluate(cost, x);
    return out;
  };
  const Eigen::MatrixXd num = test::numeric_jacobian(
      [&](const Eigen::VectorXd& x) { return f(x.data()); }, Eigen::Map<Eigen::VectorXd>(pose, 7));
  EXPECT_LT((num - Eigen::MatrixXd(J)).norm(), tight_tolerance(num)) << num << "\n" << J;

  SE3Manifold se3;
  Eigen::Matrix<double, 7, 6, Eigen::RowMajor> P;
  se3.PlusJacobian(pose, P.data());
  const Eigen::MatrixXd num_xi = test::numeric_jacobian(
      [&](const Eigen::VectorXd& xi) {
        double moved[7];
        se3.Plus(pose, xi.data(), moved);
        return f(moved);
      },
      Eigen::VectorXd::Zero(6));
  EXPECT_LT((num_xi - Eigen::MatrixXd(J) * P).norm(), tight_tolerance(num_xi));
}

// A point of an object that slid on the plane n_w between the last frame and now, as a camera at
// T_c_w measures it, optionally lifted by `lift` along n_w.
ConstrainedPointMeasurement slid_point(const SE3& T_c_w, const Eigen::Vector3d& n_w,
                                       const Eigen::Vector3d& p_last_w, const SE3& slide,
                                       double lift, double information) {
  ConstrainedPointMeasurement m;
  m.p_last_w = p_last_w;
  m.p_c = T_c_w * (slide * p_last_w + lift * n_w);
  m.n_w = n_w;
  m.information = information;
  return m;
}

// A line of the object that slid, from its last-frame direction.
ConstrainedLineMeasurement slid_line(const SE3& T_c_w, const Eigen::Vector3d& n_w,
                                     const Eigen::Vector3d& s_last_w, const SE3& slide,
                                     double information) {
  ConstrainedLineMeasurement m;
  m.s_last_w = s_last_w;
  m.s_c = T_c_w.rotation() * (slide.rotation() * s_last_w);
  m.n_w = n_w;
  m.information = information;
  return m;
}

TEST(ConstrainedPointError, JacobiansMatchNumericAtRandomPoses) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> coord(-3.0, 3.0), lift(-0.3, 0.3);
  for (int trial = 0; trial < 8; ++trial) {
    const SE3 T_c_w = random_pose(rng);
    const Eigen::Vector3d n_w = random_unit(rng);
    const Eigen::Vector3d p_last(coord(rng), coord(rng), coord(rng));
    // A non-unit normal must give the same residual as the unit one.
    auto m = slid_point(T_c_w, n_w, p_last, random_slide(n_w, rng), lift(rng), 400.0);
    SCOPED_TRACE(trial);
    const PoseOnlyConstrainedPointError cost(m);
    check_pose_jacobian(cost, T_c_w);
    double pose[7];
    pose_to_block(T_c_w, pose);
    const double r = evaluate(cost, pose);
    EXPECT_NEAR(r, 20.0 * constrained_point_error(T_c_w, m), 1e-10);
    EXPECT_NEAR(r * r, constrained_point_chi2(T_c_w, m), 1e-9 * (1.0 + r * r));
    m.n_w *= 3.0;
    EXPECT_NEAR(evaluate(PoseOnlyConstrainedPointError(m), pose), r, 1e-12);
  }
}

TEST(ConstrainedLineError, JacobiansMatchNumericAtRandomPoses) {
  std::mt19937 rng(37);
  std::uniform_real_distribution<double> elevation(-1.3, 1.3), tilt(-0.3, 0.3);
  int checked = 0;
  while (checked < 8) {
    const SE3 T_c_w = random_pose(rng);
    const Eigen::Vector3d n_w = random_unit(rng);
    const double el = elevation(rng);
    const double el_now = el + tilt(rng);
    // Away from the kink of |cos| (numeric differences straddle it).
    if (std::abs(el_now) < 0.05) continue;
    ConstrainedLineMeasurement m;
    m.s_last_w = 2.5 * direction_at_elevation(n_w, el, rng);  // non-unit on purpose
    m.s_c = 0.7 * (T_c_w.rotation() * direction_at_elevation(n_w, el_now, rng));
    m.n_w = n_w;
    m.information = 2500.0;
    SCOPED_TRACE(checked);
    const PoseOnlyConstrainedLineError cost(m);
    check_pose_jacobian(cost, T_c_w);
    double pose[7];
    pose_to_block(T_c_w, pose);
    const double r = evaluate(cost, pose);
    EXPECT_NEAR(r, 50.0 * (std::abs(std::sin(el)) - std::abs(std::sin(el_now))), 1e-10);
    EXPECT_NEAR(r, 50.0 * constrained_line_error(T_c_w, m), 1e-10);
    EXPECT_NEAR(r * r, constrained_line_chi2(T_c_w, m), 1e-9 * (1.0 + r * r));
    ++checked;
  }
}

// An object that slid (rotated about the normal, moved along the plane) satisfies (9) and (10)
// exactly at the true pose, although every one of its points and lines moved in the world.
TEST(ConstrainedResiduals, ZeroAtTruePoseForAnObjectSlidOnTheFloor) {
  std::mt19937 rng(41);
  std::uniform_real_distribution<double> coord(-2.0, 2.0), elevation(-1.5, 1.5);
  for (int trial = 0; trial < 10; ++trial) {
    const SE3 T_c_w = random_pose(rng);
    const Eigen::Vector3d n_w = random_unit(rng);
    const SE3 slide = random_slide(n_w, rng);
    double pose[7];
    pose_to_block(T_c_w, pose);
    for (int i = 0; i < 5; ++i) {
      const Eigen::Vector3d p_last(coord(rng), coord(rng), coord(rng));
      const auto point = slid_point(T_c_w, n_w, p_last, slide, 0.0, 1e4);
      EXPECT_GT((slide * p_last - p_last).norm(), 1e-3);  // it did move
      EXPECT_NEAR(evaluate(PoseOnlyConstrainedPointError(point), pose), 0.0, 1e-10);
      EXPECT_NEAR(constrained_point_error(T_c_w, point), 0.0, 1e-12);

      const auto line =
          slid_line(T_c_w, n_w, direction_at_elevation(n_w, elevation(rng), rng), slide, 1e4);
      EXPECT_NEAR(evaluate(PoseOnlyConstrainedLineError(line), pose), 0.0, 1e-10);
      EXPECT_NEAR(constrained_line_error(T_c_w, line), 0.0, 1e-12);
    }
  }
}

// A point that left the floor (lifted or dropped by h along n_w) gives e_cp = -h: the residual
// is last minus current height, whitened to -h * sqrt(information).
TEST(ConstrainedPointError, DetectsVerticalDisplacement) {
  std::mt19937 rng(43);
  const SE3 T_c_w = random_pose(rng);
  const Eigen::Vector3d n_w = random_unit(rng);
  const SE3 slide = random_slide(n_w, rng);
  const double sigma = 0.01;  // 1 cm
  double pose[7];
  pose_to_block(T_c_w, pose);
  for (const double h : {0.2, 0.05, 0.01, -0.03, -0.15}) {
    const auto m =
        slid_point(T_c_w, n_w, Eigen::Vector3d(0.4, -1.0, 2.5), slide, h, 1.0 / (sigma * sigma));
    EXPECT_NEAR(evaluate(PoseOnlyConstrainedPointError(m), pose), -h / sigma, 1e-9) << h;
    EXPECT_NEAR(constrained_point_error(T_c_w, m), -h, 1e-12);
    EXPECT_NEAR(constrained_point_chi2(T_c_w, m), h * h / (sigma * sigma), 1e-8);
  }
  // A move along the plane alone is invisible to (9).
  auto m = slid_point(T_c_w, n_w, Eigen::Vector3d(0.4, -1.0, 2.5), slide, 0.0, 1e4);
  m.p_c += T_c_w.rotation() * (0.3 * random_orthogonal(n_w, rng));
  EXPECT_NEAR(evaluate(PoseOnlyConstrainedPointError(m), pose), 0.0, 1e-9);
}

// A line that tipped over (its angle to the floor changed) is detected; the value is the change of
// the sine of its elevation.
TEST(ConstrainedLineError, DetectsTilt) {
  std::mt19937 rng(47);
  const SE3 T_c_w = random_pose(rng);
  const Eigen::Vector3d n_w = random_unit(rng);
  double pose[7];
  pose_to_block(T_c_w, pose);
  const double sigma = 0.02;
  for (const auto& [el, el_now] : {std::pair{0.0, 0.2}, std::pair{0.3, 0.6}, std::pair{1.2, 0.9},
                                   std::pair{std::numbers::pi / 2, 1.0}}) {
    ConstrainedLineMeasurement m;
    m.s_last_w = direction_at_elevation(n_w, el, rng);
    m.s_c = T_c_w.rotation() * direction_at_elevation(n_w, el_now, rng);
    m.n_w = n_w;
    m.information = 1.0 / (sigma * sigma);
    const double expected = std::sin(el) - std::sin(el_now);
    EXPECT_NEAR(constrained_line_error(T_c_w, m), expected, 1e-12) << el;
    EXPECT_NEAR(evaluate(PoseOnlyConstrainedLineError(m), pose), expected / sigma, 1e-9) << el;
  }
}

// The residual, its Jacobian and the unwhitened error do not change when either direction is
// flipped, including for a horizontal last-frame line (the kink of |cos|).
TEST(ConstrainedLineError, InvariantToDirectionSign) {
  std::mt19937 rng(53);
  for (int trial = 0; trial < 6; ++trial) {
    const SE3 T_c_w = random_pose(rng);
    const Eigen::Vector3d n_w = random_unit(rng);
    double pose[7];
    pose_to_block(T_c_w, pose);
    const double el = trial < 3 ? 0.0 : 0.4 * trial - 1.5;  // three horizontal lines
    ConstrainedLineMeasurement m;
    m.s_last_w = direction_at_elevation(n_w, el, rng);
    m.s_c = T_c_w.rotation() * direction_at_elevation(n_w, el + 0.1 + 0.05 * trial, rng);
    m.n_w = n_w;
    m.information = 100.0;
    RowJPose1 J;
    const double r = evaluate(PoseOnlyConstrainedLineError(m), pose, &J);
    EXPECT_GT(std::abs(r), 0.1);
    for (const double sign_last : {1.0, -1.0}) {
      for (const double sign_c : {1.0, -1.0}) {
        ConstrainedLineMeasurement flipped = m;
        flipped.s_last_w *= sign_last;
        flipped.s_c *= sign_c;
        RowJPose1 J_flipped;
        EXPECT_DOUBLE_EQ(evaluate(PoseOnlyConstrainedLineError(flipped), pose, &J_flipped), r);
        EXPECT_LT((J_flipped - J).norm(), 1e-12 * (1.0 + J.norm()));
        EXPECT_DOUBLE_EQ(constrained_line_error(T_c_w, flipped), constrained_line_error(T_c_w, m));
      }
    }
    // A slid object with its current direction reversed is still consistent.
    const SE3 slide = random_slide(n_w, rng);
    auto line = slid_line(T_c_w, n_w, m.s_last_w, slide, 100.0);
    line.s_c = -line.s_c;
    EXPECT_NEAR(evaluate(PoseOnlyConstrainedLineError(line), pose), 0.0, 1e-10);
  }
}

// --- Pose optimisation with constrained moving objects ---------------------------------------

// Static world points in front of a camera at T_c_w, measured with pixel noise (RGB-D).
std::vector<PoseObservation> make_points(const PinholeCamera& cam, const SE3& T_c_w, int n,
                                         double z_min, double z_max, double noise_px,
                                         std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 640.0), v(0.0, 480.0), z(z_min, z_max);
  std::normal_distribution<double> noise(0.0, noise_px);
  std::vector<PoseObservation> out;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p_c = cam.unproject({u(rng), v(rng)}, z(rng));
    PoseObservation obs;
    obs.p_w = T_c_w.inverse() * p_c;
    obs.measurement.uv = cam.project(p_c) + Eigen::Vector2d(noise(rng), noise(rng));
    obs.measurement.u_right = cam.right_u(cam.project(p_c).x(), p_c.z()) + noise(rng);
    obs.measurement.with_depth = true;
    obs.measurement.information = 1.0 / (noise_px * noise_px);
    obs.measurement.right_information = obs.measurement.information;
    out.push_back(obs);
  }
  return out;
}

// The floor of the test scene (world frame, pointing up, i.e. along -y of a level camera), and a
// chair that slid on it between the last frame and now.
struct MovingChair {
  Eigen::Vector3d n_w = Eigen::Vector3d(0.05, -1.0, 0.1).normalized();
  SE3 slide;
};

// Visible points of the chair: measured now in the camera at T_c_w (with depth noise), known in
// the last frame in the world (with the same noise). sigma is the noise per coordinate.
std::vector<ConstrainedPointMeasurement> make_constrained_points(const PinholeCamera& cam,
                                                                 const SE3& T_c_w,
                                                                 const MovingChair& chair, int n,
                                                                 double sigma, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(100.0, 540.0), v(200.0, 460.0), z(1.5, 3.0);
  std::normal_distribution<double> noise(0.0, sigma);
  const auto jitter = [&] { return Eigen::Vector3d(noise(rng), noise(rng), noise(rng)); };
  std::vector<ConstrainedPointMeasurement> out;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p_c = cam.unproject({u(rng), v(rng)}, z(rng));
    ConstrainedPointMeasurement m;
    m.p_last_w = chair.slide.inverse() * (T_c_w.inverse() * p_c) + jitter();
    m.p_c = p_c + jitter();
    m.n_w = chair.n_w;
    // Both ends carry the noise; only its component along n_w enters the residual.
    m.information = 1.0 / (2.0 * sigma * sigma);
    out.push_back(m);
  }
  return out;
}

// Lines of the chair at elevations in [-60, 60] degrees, a quarter of them horizontal, with
// direction noise `sigma` per component and each current direction flipped at random.
std::vector<ConstrainedLineMeasurement> make_constrained_lines(const SE3& T_c_w,
                                                               const MovingChair& chair, int n,
                                                               double sigma, std::mt19937& rng) {
  std::uniform_real_distribution<double> elevation(-1.05, 1.05);
  std::normal_distribution<double> noise(0.0, sigma);
  std::bernoulli_distribution flip(0.5);
  std::vector<ConstrainedLineMeasurement> out;
  for (int i = 0; i < n; ++i) {
    const double el = i % 4 == 0 ? 0.0 : elevation(rng);
    const Eigen::Vector3d s_now_w = direction_at_elevation(chair.n_w, el, rng);
    ConstrainedLineMeasurement m;
    m.s_last_w = chair.slide.rotation().transpose() * s_now_w;
    m.s_c = T_c_w.rotation() * s_now_w + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    if (flip(rng)) m.s_c = -m.s_c;
    m.n_w = chair.n_w;
    m.information = 1.0 / (sigma * sigma);
    out.push_back(m);
  }
  return out;
}

const SE3& truth_pose() {
  static const SE3 truth = SE3::exp((Vector6d() << 0.3, -0.1, 0.2, 0.1, 0.2, -0.05).finished());
  return truth;
}

SE3 perturbed(const SE3& T) {
  return SE3::exp((Vector6d() << 0.05, -0.04, 0.03, 0.03, -0.02, 0.02).finished()) * T;
}

std::pair<double, double> pose_error(const SE3& estimate, const SE3& truth) {
  const Vector6d e = (estimate * truth.inverse()).log();
  return {e.tail<3>().norm(), e.head<3>().norm()};
}

// Height of the camera centre above the floor (up to the floor's offset) and the angle between
// the floor normal as two poses see it: the quantities (9) and (10) constrain.
double height_error(const SE3& estimate, const SE3& truth, const Eigen::Vector3d& n_w) {
  return n_w.dot(estimate.inverse().translation() - truth.inverse().translation());
}
double tilt_error(const SE3& estimate, const SE3& truth, const Eigen::Vector3d& n_w) {
  const Eigen::Vector3d a = estimate.rotation() * n_w, b = truth.rotation() * n_w;
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

MovingChair make_chair() {
  MovingChair chair;
  // Turned by 0.4 rad about the floor normal through a point in front of the camera, and pushed
  // 0.3 m along the floor.
  const Eigen::Vector3d pivot = truth_pose().inverse() * Eigen::Vector3d(0.0, 0.5, 2.0);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.4, chair.n_w).toRotationMatrix();
  const Eigen::Vector3d along = chair.n_w.cross(Eigen::Vector3d::UnitZ()).normalized();
  chair.slide = SE3(R, pivot - R * pivot + 0.3 * along);
  return chair;
}

TEST(PoseOptimizer, ConstrainedObjectConvergesAndFlagsLiftedPoints) {
  std::mt19937 rng(505);
  const PinholeCamera cam = test::make_camera();
  const SE3& truth = truth_pose();
  const MovingChair chair = make_chair();
  PoseProblem problem;
  problem.points = make_points(cam, truth, 30, 0.8, 4.0, 0.5, rng);
  problem.constrained_points = make_constrained_points(cam, truth, chair, 40, 0.01, rng);
  problem.constrained_lines = make_constrained_lines(truth, chair, 20, 0.01, rng);
  // Outliers: every eighth chair point was lifted by 10-20 cm (someone picked the chair up by its
  // back), and every seventh chair line tipped by 25 degrees towards the normal.
  std::uniform_real_distribution<double> lift(0.1, 0.2);
  for (std::size_t i = 0; i < problem.constrained_points.size(); i += 8)
    problem.constrained_points[i].p_c += truth.rotation() * (lift(rng) * chair.n_w);
  for (std::size_t i = 3; i < problem.constrained_lines.size(); i += 7) {
    auto& m = problem.constrained_lines[i];
    const Eigen::Vector3d s_w = truth.rotation().transpose() * m.s_c;
    const double sign = s_w.dot(chair.n_w) < 0.0 ? -1.0 : 1.0;  // away from horizontal
    const Eigen::Vector3d axis = sign * s_w.cross(chair.n_w).normalized();
    m.s_c = truth.rotation() * (Eigen::AngleAxisd(0.44, axis) * s_w);
  }

  const auto result = optimize_pose(cam, perturbed(truth), problem, PoseOptimizerOptions{});
  const auto [rot, trans] = pose_error(result.T_c_w, truth);
  EXPECT_LT(rot, 0.003);
  EXPECT_LT(trans, 0.005);
  EXPECT_LT(std::abs(height_error(result.T_c_w, truth, chair.n_w)), 0.003);
  ASSERT_EQ(result.constrained_point_inlier.size(), 40u);
  ASSERT_EQ(result.constrained_line_inlier.size(), 20u);
  int lost = 0, inliers = 0;
  for (std::size_t i = 0; i < problem.constrained_points.size(); ++i) {
    if (i % 8 == 0) {
      EXPECT_FALSE(result.constrained_point_inlier[i]) << "constrained point " << i;
    } else if (!result.constrained_point_inlier[i]) {
      ++lost;
    }
    inliers += result.constrained_point_inlier[i] ? 1 : 0;
  }
  EXPECT_LT(lost, 5);  // the 95% test drops about 5% of good ones
  EXPECT_EQ(result.num_constrained_point_inliers, inliers);
  lost = inliers = 0;
  for (std::size_t i = 0; i < problem.constrained_lines.size(); ++i) {
    if (i % 7 == 3) {
      EXPECT_FALSE(result.constrained_line_inlier[i]) << "constrained line " << i;
    } else if (!result.constrained_line_inlier[i]) {
      ++lost;
    }
    inliers += result.constrained_line_inlier[i] ? 1 : 0;
  }
  EXPECT_LT(lost, 3);
  EXPECT_EQ(result.num_constrained_line_inliers, inliers);
  EXPECT_GE(result.num_inliers, 25);
}

// Few, distant, noisy static points (6 at 4-8 m, 2 px, so their stereo depth is off by metres)
// leave the camera's height and tilt poorly determined: pitch and vertical translation trade off
// for a narrow field of view. A chair that slid on the floor nearby (40 points with 5 mm depth
// noise, 20 lines) pins both down, although it moved. Every term is weighted by its true noise,
// so the comparison is fair.
TEST(PoseOptimizer, ConstrainedTermsImproveHeightAndTilt) {
  const PinholeCamera cam = test::make_camera();
  const SE3& truth = truth_pose();
  const MovingChair chair = make_chair();
  double height_points = 0.0, height_both = 0.0, tilt_points = 0.0, tilt_both = 0.0;
  int height_better = 0, tilt_better = 0;
  constexpr int kTrials = 10;
  for (int trial = 0; trial < kTrials; ++trial) {
    std::mt19937 rng(700 + trial);
    PoseProblem problem;
    problem.points = make_points(cam, truth, 6, 4.0, 8.0, 2.0, rng);
    const auto points_only = optimize_pose(cam, perturbed(truth), problem, PoseOptimizerOptions{});
    problem.constrained_points = make_constrained_points(cam, truth, chair, 40, 0.005, rng);
    problem.constrained_lines = make_constrained_lines(truth, chair, 20, 0.005, rng);
    const auto with_chair = optimize_pose(cam, perturbed(truth), problem, PoseOptimizerOptions{});

    const double hp = std::abs(height_error(points_only.T_c_w, truth, chair.n_w));
    const double hb = std::abs(height_error(with_chair.T_c_w, truth, chair.n_w));
    const double tp = tilt_error(points_only.T_c_w, truth, chair.n_w);
    const double tb = tilt_error(with_chair.T_c_w, truth, chair.n_w);
    height_points += hp * hp;
    height_both += hb * hb;
    tilt_points += tp * tp;
    tilt_both += tb * tb;
    height_better += hb < hp ? 1 : 0;
    tilt_better += tb < tp ? 1 : 0;
    // The constrained estimate is good in absolute terms too.
    EXPECT_LT(hb, 0.01) << trial;
    EXPECT_LT(tb, 0.005) << trial;
  }
  height_points = std::sqrt(height_points / kTrials);
  height_both = std::sqrt(height_both / kTrials);
  tilt_points = std::sqrt(tilt_points / kTrials);
  tilt_both = std::sqrt(tilt_both / kTrials);
  // About 4 mm against 6 cm, and 2 mrad against 11 mrad. The chair's terms have a noise floor of
  // their own (~1.5 mrad of tilt), so points alone can get luckier on a single trial's tilt.
  EXPECT_LT(height_both, 0.2 * height_points) << height_both << " vs " << height_points;
  EXPECT_LT(tilt_both, 0.35 * tilt_points) << tilt_both << " vs " << tilt_points;
  EXPECT_EQ(height_better, kTrials);
  EXPECT_GE(tilt_better, 7);
}

// Constraint terms cannot fix the pose on their own: with no landmark the pose is returned as it
// came, every constraint term counted as an inlier (none was tested).
TEST(PoseOptimizer, ConstraintTermsAloneLeaveThePoseUntouched) {
  std::mt19937 rng(606);
  const PinholeCamera cam = test::make_camera();
  const MovingChair chair = make_chair();
  PoseProblem problem;
  problem.constrained_points = make_constrained_points(cam, truth_pose(), chair, 20, 0.01, rng);
  problem.constrained_lines = make_constrained_lines(truth_pose(), chair, 10, 0.01, rng);
  const SE3 initial = perturbed(truth_pose());
  const auto result = optimize_pose(cam, initial, problem, PoseOptimizerOptions{});
  EXPECT_EQ((result.T_c_w.log() - initial.log()).norm(), 0.0);
  EXPECT_EQ(result.constrained_point_inlier, std::vector<bool>(20, true));
  EXPECT_EQ(result.constrained_line_inlier, std::vector<bool>(10, true));
}

TEST(PoseOptimizer, EmptyConstraintsGiveEmptyFlags) {
  std::mt19937 rng(607);
  const PinholeCamera cam = test::make_camera();
  PoseProblem problem;
  problem.points = make_points(cam, truth_pose(), 40, 0.8, 4.0, 0.5, rng);
  const auto result = optimize_pose(cam, perturbed(truth_pose()), problem, PoseOptimizerOptions{});
  EXPECT_TRUE(result.constrained_point_inlier.empty());
  EXPECT_TRUE(result.constrained_line_inlier.empty());
  EXPECT_EQ(result.num_constrained_point_inliers, 0);
  EXPECT_EQ(result.num_constrained_line_inliers, 0);
}

TEST(PoseOptimizer, OptionsCheckCoversConstraintThreshold) {
  PoseOptimizerOptions o;
  EXPECT_DOUBLE_EQ(o.chi2_constraint, 3.841);
  EXPECT_FALSE(o.check().has_value());
  o.chi2_constraint = 0.0;
  EXPECT_TRUE(o.check().has_value());
  o.chi2_constraint = std::nan("");
  EXPECT_TRUE(o.check().has_value());
}

}  // namespace
}  // namespace mcslam::optim
