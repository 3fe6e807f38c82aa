#include "mcslam/io/camera_presets.hpp"

#include <gtest/gtest.h>

namespace mcslam::io {
namespace {

TEST(CameraPresets, ByFolderName) {
  const auto fr1 = camera_preset_for_sequence("rgbd_dataset_freiburg1_rpy");
  ASSERT_TRUE(fr1.has_value());
  EXPECT_EQ(fr1->fx, 517.306408);
  EXPECT_EQ(fr1->fy, 516.469215);
  EXPECT_EQ(fr1->cx, 318.643040);
  EXPECT_EQ(fr1->cy, 255.313989);
  EXPECT_EQ(fr1->distortion,
            (std::array<double, 5>{0.262383, -0.953104, -0.005358, 0.002628, 1.163314}));
  EXPECT_EQ(fr1->width, 640);
  EXPECT_EQ(fr1->height, 480);
  EXPECT_EQ(fr1->depth_factor, 5000.0);
  EXPECT_EQ(fr1->bf, 40.0);

  const auto fr2 = camera_preset_for_sequence("rgbd_dataset_freiburg2_desk_with_person");
  ASSERT_TRUE(fr2.has_value());
  EXPECT_EQ(fr2->fx, 520.908620);
  EXPECT_EQ(fr2->distortion[4], 0.917205);

  const auto fr3 = camera_preset_for_sequence("RGBD_DATASET_FREIBURG3_WALKING_XYZ");
  ASSERT_TRUE(fr3.has_value());
  EXPECT_EQ(fr3->fx, 535.4);
  EXPECT_EQ(fr3->cy, 247.6);
  EXPECT_FALSE(fr3->has_distortion());

  const auto bonn = camera_preset_for_sequence("rgbd_bonn_crowd");
  ASSERT_TRUE(bonn.has_value());
  EXPECT_EQ(bonn->fx, 542.822841);
  EXPECT_EQ(bonn->distortion,
            (std::array<double, 5>{0.039903, -0.099343, -0.000730, -0.000144, 0.0}));

  EXPECT_FALSE(camera_preset_for_sequence("kitti_00").has_value());
  EXPECT_FALSE(camera_preset_for_sequence("").has_value());
}

TEST(CameraPresets, ByNameAllValid) {
  const auto names = camera_preset_names();
  EXPECT_EQ(names, (std::vector<std::string>{"tum_fr1", "tum_fr2", "tum_fr3", "bonn"}));
  for (const std::string& name : names) {
    const auto camera = camera_preset(name);
    ASSERT_TRUE(camera.has_value()) << name;
    EXPECT_FALSE(camera->check().has_value()) << name << ": " << camera->check().value_or("");
  }
  EXPECT_EQ(camera_preset("TUM_FR1")->fx, 517.306408);
  EXPECT_EQ(camera_preset("tum_fr2")->cx, 325.141442);
  EXPECT_EQ(camera_preset("bonn")->cy, 237.756098);
  EXPECT_FALSE(camera_preset("tum_fr4").has_value());
}

}  // namespace
}  // namespace mcslam::io
