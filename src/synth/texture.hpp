#pragma once
// Procedural texture generation (private to the synth module).

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

#include "mcslam/synth/scene.hpp"

namespace mcslam::synth::detail {

enum class SurfaceKind { kFloor, kCeiling, kWall, kBoxFace };

/// Metres per level-0 texel of every generated texture.
inline constexpr double kTexelSize = 0.003;

/// A level-0 texture image (CV_8UC3, BGR) covering size_u x size_v metres (padded up to a
/// multiple of 64 texels so that the mip levels halve exactly). Deterministic from the seed.
cv::Mat generate_texture_image(double size_u, double size_v, TextureLevel level, SurfaceKind kind,
                               std::uint64_t seed);

/// The mip pyramid of a level-0 image: each level is the 2x2 box average of the previous one,
/// down to a smallest side of about 8 texels.
std::vector<cv::Mat> build_mips(const cv::Mat& level0);

}  // namespace mcslam::synth::detail
