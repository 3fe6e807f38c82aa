#include "mcslam/optim/bundle_solver.hpp"

#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>
#include <gtest/gtest.h>

#include <deque>
#include <random>

#include "mcslam/optim/line_residual.hpp"
#include "mcslam/optim/plane_residual.hpp"
#include "mcslam/optim/reprojection.hpp"
#include "mcslam/optim/se3_manifold.hpp"
#include "support/test_camera.hpp"

namespace mcslam::optim {
namespace {

/// Four keyframes (the first fixed) looking at a room's worth of points (with and without depth,
/// a tenth of them gross outliers), line segments and two planes, observed with noise; the free
/// poses and every landmark start perturbed. Fixed seed.
struct Bundle {
  std::vector<double> poses;
  std::vector<bool> fixed{true, false, false, false};
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Matrix<double, 6, 1>> segments;
  std::vector<Eigen::Vector4d> planes;
  std::deque<ReprojectionError<3>> rgbd;
  std::deque<ReprojectionError<2>> mono;
  std::deque<LineSegmentError> lines;
  std::deque<PlaneError> plane_costs;
  std::vector<BundleTerm> terms;
  SegmentManifold segment_manifold;
  PlaneManifold plane_manifold;
  std::vector<BundleLandmark> landmarks;

  explicit Bundle(unsigned seed, bool pinned_segments) {
    std::mt19937 rng(seed);
    const PinholeCamera cam = test::make_camera();
    std::normal_distribution<double> noise(0.0, 0.7), small(0.0, 0.02);
    std::uniform_real_distribution<double> x(-1.5, 1.5), y(-1.0, 1.0), z(2.5, 5.0),
        gross(20.0, 40.0);
    std::vector<SE3> truth;
    for (int k = 0; k < 4; ++k)
      truth.push_back(SE3::exp(
          (Vector6d() << 0.15 * k, -0.05 * k, 0.03 * k, 0.02 * k, 0.04 * k, -0.01 * k).finished()));
    poses.resize(truth.size() * kPoseSize);
    for (std::size_t k = 0; k < truth.size(); ++k) {
      const Vector6d error = k == 0
                                 ? Vector6d::Zero()
                                 : Vector6d((Vector6d() << small(rng), small(rng), small(rng),
                                             0.5 * small(rng), 0.5 * small(rng), 0.5 * small(rng))
                                                .finished());
      pose_to_block(SE3::exp(error) * truth[k], &poses[k * kPoseSize]);
    }
    const Eigen::Vector3d jitter(0.03, -0.02, 0.04);
    for (int i = 0; i < 120; ++i) {
      const Eigen::Vector3d p(x(rng), y(rng), z(rng));
      points.push_back(p + (i % 2 ? jitter : -jitter));
      for (std::size_t k = 0; k < truth.size(); ++k) {
        const Eigen::Vector3d p_c = truth[k] * p;
        PointMeasurement m;
        m.uv = cam.project(p_c) + Eigen::Vector2d(noise(rng), noise(rng));
        if ((i + static_cast<int>(k)) % 10 == 0) m.uv.y() += gross(rng);
        m.u_right = cam.right_u(m.uv.x(), p_c.z()) + noise(rng);
        m.with_depth = (i + static_cast<int>(k)) % 3 != 0;
        const ceres::CostFunction* cost =
            m.with_depth ? static_cast<const ceres::CostFunction*>(&rgbd.emplace_back(cam, m))
                         : &mono.emplace_back(cam, m);
        terms.push_back({cost, static_cast<int>(k), i, m.with_depth ? 2.8 : 2.45});
      }
    }
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d s(x(rng), y(rng), z(rng)), e(x(rng), y(rng), z(rng));
      segments.push_back((Eigen::Matrix<double, 6, 1>() << s + jitter, e - jitter).finished());
      for (std::size_t k = 0; k < truth.size(); ++k) {
        const Eigen::Vector3d a =
            (cam.project(truth[k] * s) + Eigen::Vector2d(noise(rng), noise(rng))).homogeneous();
        const Eigen::Vector3d b =
            (cam.project(truth[k] * e) + Eigen::Vector2d(noise(rng), noise(rng))).homogeneous();
        LineMeasurement m;
        m.coefficients = a.cross(b) / a.cross(b).head<2>().norm();
        terms.push_back({&lines.emplace_back(cam, m), static_cast<int>(k), 120 + i, 2.45});
      }
    }
    for (const Eigen::Vector4d& plane_w :
         {Eigen::Vector4d(0.0, -1.0, 0.0, 1.2), Eigen::Vector4d(0.0, 0.0, -1.0, 5.0)}) {
      planes.push_back(plane_w + Eigen::Vector4d(0.01, 0.0, -0.01, 0.03));
      planes.back().head<3>().normalize();
      for (std::size_t k = 0; k < truth.size(); ++k) {
        PlaneMeasurement m;
        m.normal = truth[k].rotation() * plane_w.head<3>();
        m.d = plane_w.w() - m.normal.dot(truth[k].translation());
        m.angle_information = 1.0 / (0.01 * 0.01);
        m.distance_information = 1.0 / (0.02 * 0.02);
        terms.push_back({&plane_costs.emplace_back(m), static_cast<int>(k),
                         128 + static_cast<int>(planes.size()) - 1, 2.8});
      }
    }
    for (auto& p : points) landmarks.push_back({p.data(), 3, nullptr});
    for (auto& s : segments)
      landmarks.push_back({s.data(), 6, pinned_segments ? &segment_manifold : nullptr});
    for (auto& p : planes) landmarks.push_back({p.data(), 4, &plane_manifold});
  }

  /// The same problem, solved by Ceres in place.
  void solve_with_ceres(int iterations) {
    std::deque<ceres::HuberLoss> losses;
    ceres::Problem::Options o;
    o.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    o.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    o.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(o);
    SE3Manifold pose_manifold;
    for (const BundleTerm& t : terms)
      problem.AddResidualBlock(const_cast<ceres::CostFunction*>(t.cost),
                               &losses.emplace_back(t.huber_delta), &poses[t.pose * kPoseSize],
                               landmarks[static_cast<std::size_t>(t.landmark)].x);
    for (std::size_t k = 0; k < fixed.size(); ++k) {
      problem.SetManifold(&poses[k * kPoseSize], &pose_manifold);
      if (fixed[k]) problem.SetParameterBlockConstant(&poses[k * kPoseSize]);
    }
    for (const BundleLandmark& l : landmarks)
      if (l.manifold) problem.SetManifold(l.x, const_cast<ceres::Manifold*>(l.manifold));
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::DENSE_SCHUR;
    options.max_num_iterations = iterations;
    options.function_tolerance = 1e-15;
    options.parameter_tolerance = 1e-15;
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    ASSERT_TRUE(summary.IsSolutionUsable());
  }
};

/// Every parameter of a and b the same, to the bit.
bool unchanged(const Bundle& a, const Bundle& b) {
  return a.poses == b.poses && a.points == b.points && a.segments == b.segments &&
         a.planes == b.planes;
}

/// The largest difference between a and b's poses (tangent norm), points, planes and segments.
double largest_difference(const Bundle& a, const Bundle& b) {
  double d = 0.0;
  for (std::size_t k = 0; k < a.fixed.size(); ++k)
    d = std::max(d, (block_to_pose(&a.poses[k * kPoseSize]) *
                     block_to_pose(&b.poses[k * kPoseSize]).inverse())
                        .log()
                        .norm());
  for (std::size_t i = 0; i < a.points.size(); ++i)
    d = std::max(d, (a.points[i] - b.points[i]).norm());
  // A segment's endpoints are determined across its line only: residual (7) hardly changes when
  // they slide along it (free in the robust stage), so each endpoint is compared with b's line.
  for (std::size_t i = 0; i < a.segments.size(); ++i) {
    const Eigen::Vector3d s = b.segments[i].head<3>();
    const Eigen::Vector3d u = (b.segments[i].tail<3>() - s).normalized();
    for (const Eigen::Vector3d& p :
         {Eigen::Vector3d(a.segments[i].head<3>()), Eigen::Vector3d(a.segments[i].tail<3>())})
      d = std::max(d, ((p - s) - (p - s).dot(u) * u).norm());
  }
  for (std::size_t i = 0; i < a.planes.size(); ++i)
    d = std::max(d, (a.planes[i] - b.planes[i]).norm());
  return d;
}

TEST(BundleSolver, FindsTheMinimumCeresFindsWithEveryKindOfLandmark) {
  for (bool pinned : {false, true}) {
    Bundle ours(5, pinned), reference(5, pinned);
    const Bundle start(5, pinned);
    BundleSolverOptions options;
    options.max_iterations = 200;
    options.function_tolerance = 1e-15;
    options.parameter_tolerance = 1e-15;
    const BundleSolverSummary summary =
        solve_bundle(ours.terms, ours.poses.data(), ours.fixed, ours.landmarks, options);
    ASSERT_TRUE(summary.usable);
    EXPECT_LT(summary.final_cost, summary.initial_cost);
    reference.solve_with_ceres(200);
    // Within a micrometre (and a microradian) of Ceres's minimum, a thousandth of what the noise
    // leaves; with the endpoints free to slide the minimum is flat along them, so not tighter.
    EXPECT_LT(largest_difference(ours, reference), 1e-6) << "segments pinned: " << pinned;
    EXPECT_GT(largest_difference(ours, start), 0.01);
    // The fixed pose did not move.
    for (int i = 0; i < kPoseSize; ++i) EXPECT_EQ(ours.poses[i], start.poses[i]);
  }
}

TEST(BundleSolver, AWholeSequencesAdjustmentIsSolvedSparselyToTheSameMinimum) {
  // 150 keyframes along a corridor, each seeing the points near it only: more free poses than
  // the dense reduced system takes, so the sparse factorisation solves it.
  std::mt19937 rng(9);
  const PinholeCamera cam = test::make_camera();
  std::normal_distribution<double> noise(0.0, 0.5), small(0.0, 0.01);
  std::uniform_real_distribution<double> across(-1.0, 1.0), ahead(2.0, 3.0);
  const int n = 150;
  std::vector<double> poses(n * kPoseSize);
  std::vector<bool> fixed(n, false);
  fixed[0] = true;
  std::vector<SE3> truth;
  for (int k = 0; k < n; ++k) {
    truth.push_back(SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.1 * k, 0.0, 0.0)));
    const Vector6d error = k == 0 ? Vector6d::Zero()
                                  : Vector6d((Vector6d() << small(rng), small(rng), small(rng),
                                              small(rng), small(rng), small(rng))
                                                 .finished());
    pose_to_block(SE3::exp(error) * truth.back(), &poses[static_cast<std::size_t>(k) * kPoseSize]);
  }
  std::vector<Eigen::Vector3d> points;
  std::deque<ReprojectionError<3>> costs;
  std::vector<BundleTerm> terms;
  for (int i = 0; i < 4 * n; ++i) {
    const Eigen::Vector3d p(0.025 * i + 0.3 * across(rng), across(rng), ahead(rng));
    points.push_back(p + Eigen::Vector3d(small(rng), small(rng), small(rng)));
    const int first = std::max(0, i / 4 - 3);
    for (int k = first; k < std::min(n, first + 6); ++k) {
      const Eigen::Vector3d p_c = truth[static_cast<std::size_t>(k)] * p;
      if (std::abs(p_c.x()) > 0.9 * p_c.z()) continue;
      PointMeasurement m;
      m.uv = cam.project(p_c) + Eigen::Vector2d(noise(rng), noise(rng));
      m.u_right = cam.right_u(m.uv.x(), p_c.z()) + noise(rng);
      m.with_depth = true;
      terms.push_back({&costs.emplace_back(cam, m), k, i, 0.0});
    }
  }
  std::vector<BundleLandmark> landmarks;
  for (auto& p : points) landmarks.push_back({p.data(), 3, nullptr});
  std::vector<double> reference_poses = poses;
  std::vector<Eigen::Vector3d> reference_points = points;

  BundleSolverOptions options;
  options.max_iterations = 50;
  options.function_tolerance = 1e-15;
  options.parameter_tolerance = 1e-15;
  const BundleSolverSummary summary = solve_bundle(terms, poses.data(), fixed, landmarks, options);
  ASSERT_TRUE(summary.usable);
  EXPECT_LT(summary.final_cost, 0.1 * summary.initial_cost);

  ceres::Problem::Options o;
  o.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  o.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(o);
  SE3Manifold pose_manifold;
  for (const BundleTerm& t : terms)
    problem.AddResidualBlock(const_cast<ceres::CostFunction*>(t.cost), nullptr,
                             &reference_poses[static_cast<std::size_t>(t.pose) * kPoseSize],
                             reference_points[static_cast<std::size_t>(t.landmark)].data());
  for (int k = 0; k < n; ++k) {
    double* block = &reference_poses[static_cast<std::size_t>(k) * kPoseSize];
    if (!problem.HasParameterBlock(block)) continue;
    problem.SetManifold(block, &pose_manifold);
    if (fixed[static_cast<std::size_t>(k)]) problem.SetParameterBlockConstant(block);
  }
  ceres::Solver::Options ceres_options;
  ceres_options.linear_solver_type = ceres::SPARSE_SCHUR;
  ceres_options.max_num_iterations = 50;
  ceres_options.function_tolerance = 1e-15;
  ceres_options.parameter_tolerance = 1e-15;
  ceres::Solver::Summary ceres_summary;
  ceres::Solve(ceres_options, &problem, &ceres_summary);
  ASSERT_TRUE(ceres_summary.IsSolutionUsable());
  double largest = 0.0;
  for (int k = 0; k < n; ++k)
    largest = std::max(
        largest,
        (block_to_pose(&poses[static_cast<std::size_t>(k) * kPoseSize]) *
         block_to_pose(&reference_poses[static_cast<std::size_t>(k) * kPoseSize]).inverse())
            .log()
            .norm());
  for (std::size_t i = 0; i < points.size(); ++i)
    largest = std::max(largest, (points[i] - reference_points[i]).norm());
  EXPECT_LT(largest, 1e-6);
}

TEST(BundleSolver, WithEveryPoseFixedTheLandmarksAloneMove) {
  Bundle ours(10, true), reference(10, true);
  const Bundle start(10, true);
  ours.fixed.assign(4, true);
  reference.fixed.assign(4, true);
  BundleSolverOptions options;
  options.max_iterations = 100;
  options.function_tolerance = 1e-15;
  options.parameter_tolerance = 1e-15;
  ASSERT_TRUE(
      solve_bundle(ours.terms, ours.poses.data(), ours.fixed, ours.landmarks, options).usable);
  reference.solve_with_ceres(100);
  EXPECT_EQ(ours.poses, start.poses);
  EXPECT_LT(largest_difference(ours, reference), 1e-6);
  EXPECT_GT(largest_difference(ours, start), 0.01);
}

TEST(BundleSolver, ASetAbortFlagStopsBeforeTheFirstStep) {
  Bundle bundle(6, false);
  const Bundle start(6, false);
  std::atomic<bool> abort{true};
  BundleSolverOptions options;
  options.abort = &abort;
  const BundleSolverSummary summary =
      solve_bundle(bundle.terms, bundle.poses.data(), bundle.fixed, bundle.landmarks, options);
  EXPECT_TRUE(summary.usable);
  EXPECT_TRUE(summary.aborted);
  EXPECT_EQ(summary.iterations, 0);
  EXPECT_TRUE(unchanged(bundle, start));
}

TEST(BundleSolver, ATermOfTheWrongShapeIsRefusedAndNothingMoves) {
  Bundle bundle(7, false);
  const Bundle start(7, false);
  // A point's residual pointed at a segment (6 doubles, the cost takes 3).
  bundle.terms.front().landmark = 120;
  EXPECT_FALSE(
      solve_bundle(bundle.terms, bundle.poses.data(), bundle.fixed, bundle.landmarks).usable);
  bundle.terms.front().landmark = 100000;
  EXPECT_FALSE(
      solve_bundle(bundle.terms, bundle.poses.data(), bundle.fixed, bundle.landmarks).usable);
  EXPECT_TRUE(unchanged(bundle, start));
}

TEST(BundleSolver, AStartThatCannotBeEvaluatedIsNotUsable) {
  Bundle bundle(8, false);
  // A point moved behind the first camera: its residual cannot be evaluated.
  bundle.points.front() = Eigen::Vector3d(0.0, 0.0, -2.0);
  const std::vector<double> poses = bundle.poses;
  EXPECT_FALSE(
      solve_bundle(bundle.terms, bundle.poses.data(), bundle.fixed, bundle.landmarks).usable);
  EXPECT_EQ(bundle.poses, poses);
}

}  // namespace
}  // namespace mcslam::optim
