#include "mcslam/core/camera.hpp"

#include <gtest/gtest.h>

#include "support/numeric_diff.hpp"
#include "support/test_camera.hpp"

namespace mcslam {
namespace {

TEST(PinholeCamera, ProjectUnprojectRoundTrip) {
  const PinholeCamera cam = test::make_camera(517.3, 516.5, 318.6, 255.3);
  const Eigen::Vector2d uv(100.25, 400.5);
  const Eigen::Vector3d p = cam.unproject(uv, 2.5);
  EXPECT_DOUBLE_EQ(p.z(), 2.5);
  EXPECT_LT((cam.project(p) - uv).norm(), 1e-12);
}

TEST(PinholeCamera, ProjectJacobianMatchesNumeric) {
  const PinholeCamera cam = test::make_camera(517.3, 516.5, 318.6, 255.3);
  const Eigen::Vector3d p(0.4, -0.3, 1.7);
  auto f = [&](const Eigen::VectorXd& x) -> Eigen::VectorXd { return cam.project(x.head<3>()); };
  const Eigen::MatrixXd J = test::numeric_jacobian(f, p);
  EXPECT_LT((J - cam.project_jacobian(p)).norm(), 1e-6);
}

TEST(PinholeCamera, RightCoordinate) {
  const PinholeCamera cam = test::make_camera(517.3, 516.5, 318.6, 255.3);
  EXPECT_DOUBLE_EQ(cam.right_u(300.0, 2.0), 300.0 - cam.bf / 2.0);
}

TEST(PinholeCamera, CheckRejectsAbsurdValues) {
  EXPECT_FALSE(test::make_camera(517.3, 516.5, 318.6, 255.3).check().has_value());
  PinholeCamera c = test::make_camera(517.3, 516.5, 318.6, 255.3);
  c.fx = 0.0;
  ASSERT_TRUE(c.check().has_value());
  EXPECT_NE(c.check()->find("fx"), std::string::npos);
  c = test::make_camera(517.3, 516.5, 318.6, 255.3);
  c.depth_factor = -5000.0;
  EXPECT_TRUE(c.check().has_value());
  c = test::make_camera(517.3, 516.5, 318.6, 255.3);
  c.width = 0;
  EXPECT_TRUE(c.check().has_value());
  c = test::make_camera(517.3, 516.5, 318.6, 255.3);
  c.cx = 1000.0;
  EXPECT_TRUE(c.check().has_value());
}

TEST(PinholeCamera, InImageBorder) {
  const PinholeCamera cam = test::make_camera(517.3, 516.5, 318.6, 255.3);
  EXPECT_TRUE(cam.in_image({0.0, 0.0}));
  EXPECT_FALSE(cam.in_image({640.0, 10.0}));
  EXPECT_FALSE(cam.in_image({5.0, 10.0}, 8.0));
}

}  // namespace
}  // namespace mcslam
