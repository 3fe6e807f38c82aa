#include "line_band_descriptor.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace mcslam::features::detail {
namespace {

/// Values of the normalised statistics are clipped here (the paper's choice, after SIFT's 0.2 for
/// 128 values): one strong edge then cannot dominate the descriptor.
constexpr float kClip = 0.4f;

/// The 32 pairs of bands whose statistics the bits compare: all pairs 1, 2, 3 and 4 bands apart
/// (8 + 7 + 6 + 5), then the pairs 5 apart (4) and the first two 6 apart: 32 x 8 = 256 bits.
/// Nearby bands first: their difference is the intensity profile across the edge, which a change
/// of viewpoint alters least.
constexpr std::array<std::array<int, 2>, 32> kPairs = [] {
  std::array<std::array<int, 2>, 32> pairs{};
  std::size_t n = 0;
  for (int gap = 1; gap < kLbdBands && n < pairs.size(); ++gap)
    for (int i = 0; i + gap < kLbdBands && n < pairs.size(); ++i) pairs[n++] = {i, i + gap};
  return pairs;
}();

void normalise(float* v, int n) {
  float s = 0.0f;
  for (int i = 0; i < n; ++i) s += v[i] * v[i];
  if (!(s > 0.0f)) return;
  const float inv = 1.0f / std::sqrt(s);
  for (int i = 0; i < n; ++i) v[i] *= inv;
}

}  // namespace

LineBandDescriber::LineBandDescriber() {
  // The paper's weights: sigma_g = (m w - 1) / 2 across the whole region, sigma_l = w within a
  // band's neighbourhood.
  const double centre = 0.5 * (kLbdRows - 1);
  const double sigma_g = 0.5 * (kLbdRows - 1);
  for (int k = 0; k < kLbdRows; ++k) {
    const double o = k - centre;
    row_weight_[static_cast<std::size_t>(k)] =
        static_cast<float>(std::exp(-o * o / (2.0 * sigma_g * sigma_g)));
  }
  const double sigma_l = kLbdBandWidth;
  for (int j = 0; j < kLbdBands; ++j) {
    const double band_centre = j * kLbdBandWidth + 0.5 * (kLbdBandWidth - 1);
    for (int k = 0; k < kLbdRows; ++k) {
      const int band = k / kLbdBandWidth;
      if (std::abs(band - j) > 1) continue;
      const double o = k - band_centre;
      band_weight_[static_cast<std::size_t>(j)][static_cast<std::size_t>(k)] =
          static_cast<float>(std::exp(-o * o / (2.0 * sigma_l * sigma_l)));
    }
  }
}

bool LineBandDescriber::set_image(const cv::Mat& gray) {
  if (gray.empty() || gray.type() != CV_8UC1 || gray.dims != 2 || gray.rows < 3 || gray.cols < 3)
    return false;
  // Sobel's 3x3 derivative smooths across the direction it differentiates, so that one noisy
  // pixel moves a sum less; its scale (8 times the slope) cancels in the normalisation.
  cv::Sobel(gray, gx_, CV_32F, 1, 0, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  cv::Sobel(gray, gy_, CV_32F, 0, 1, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  return true;
}

LineBandDescriber::RowSums LineBandDescriber::row_sums(const Eigen::Vector2d& start,
                                                       const Eigen::Vector2d& end) const {
  RowSums rows{};
  const Eigen::Vector2d delta = end - start;
  const double length = delta.norm();
  // A segment longer than kMaxLength is not one of an image (and its samples would not fit an
  // int count).
  constexpr double kMaxLength = 1e6;
  if (gx_.empty() || !(length > 0.0) || !(length < kMaxLength) || !start.allFinite() ||
      !end.allFinite())
    return rows;
  const Eigen::Vector2d d = delta / length;
  const Eigen::Vector2d n(-d.y(), d.x());
  const int steps = std::max(1, static_cast<int>(std::lround(length)) + 1);
  const double step = steps > 1 ? length / (steps - 1) : 0.0;
  const auto dx = static_cast<float>(d.x());
  const auto dy = static_cast<float>(d.y());
  const auto nx = static_cast<float>(n.x());
  const auto ny = static_cast<float>(n.y());

  const double centre = 0.5 * (kLbdRows - 1);
  // Pixel centres are at integer coordinates: the nearest pixel is floor(position + 0.5). Samples
  // off the image are skipped before any conversion; on it the offset keeps positions positive,
  // so that the conversion to int, which truncates, is the floor (std::floor would be a library
  // call on the baseline x86-64 target).
  constexpr float kOffset = 2.0f * kLbdRows + 0.5f;
  constexpr int kOffsetPixels = 2 * kLbdRows;
  const auto sx = static_cast<float>(step * d.x());
  const auto sy = static_cast<float>(step * d.y());
  const auto x_end = static_cast<float>(kOffsetPixels + gx_.cols);
  const auto y_end = static_cast<float>(kOffsetPixels + gx_.rows);
  for (int k = 0; k < kLbdRows; ++k) {
    const Eigen::Vector2d origin = start + (k - centre) * n;
    const float x0 = static_cast<float>(origin.x()) + kOffset;
    const float y0 = static_cast<float>(origin.y()) + kOffset;
    // Sums of the components and of their magnitudes: the positive part is half their sum, the
    // negative part half their difference (no branch on the sign in the inner loop).
    float across_sum = 0.0f, across_abs = 0.0f, along_sum = 0.0f, along_abs = 0.0f;
    for (int s = 0; s < steps; ++s) {
      const float fx = x0 + static_cast<float>(s) * sx;
      const float fy = y0 + static_cast<float>(s) * sy;
      if (!(fx >= kOffsetPixels && fx < x_end && fy >= kOffsetPixels && fy < y_end)) continue;
      const int x = static_cast<int>(fx) - kOffsetPixels;
      const int y = static_cast<int>(fy) - kOffsetPixels;
      const float gx = gx_.ptr<float>(y)[x];
      const float gy = gy_.ptr<float>(y)[x];
      const float across = gx * nx + gy * ny;
      const float along = gx * dx + gy * dy;
      across_sum += across;
      across_abs += std::abs(across);
      along_sum += along;
      along_abs += std::abs(along);
    }
    const float w = 0.5f * row_weight_[static_cast<std::size_t>(k)];
    rows[static_cast<std::size_t>(k)] = {w * (across_abs + across_sum),
                                         w * (across_abs - across_sum), w * (along_abs + along_sum),
                                         w * (along_abs - along_sum)};
  }

  return rows;
}

std::array<float, 8 * kLbdBands> LineBandDescriber::statistics(const Eigen::Vector2d& start,
                                                               const Eigen::Vector2d& end) const {
  const RowSums rows = row_sums(start, end);
  // Means and deviations are scaled separately (their magnitudes differ), then clipped and
  // interleaved band by band, and the whole scaled again.
  std::array<float, 4 * kLbdBands> means{};
  std::array<float, 4 * kLbdBands> deviations{};
  for (int j = 0; j < kLbdBands; ++j) {
    const int first = std::max(0, (j - 1) * kLbdBandWidth);
    const int last = std::min(kLbdRows, (j + 2) * kLbdBandWidth);
    std::array<double, 4> sum{};
    std::array<double, 4> sum2{};
    for (int k = first; k < last; ++k) {
      const float w = band_weight_[static_cast<std::size_t>(j)][static_cast<std::size_t>(k)];
      for (std::size_t c = 0; c < 4; ++c) {
        const double v = w * rows[static_cast<std::size_t>(k)][c];
        sum[c] += v;
        sum2[c] += v * v;
      }
    }
    const double count = last - first;
    for (std::size_t c = 0; c < 4; ++c) {
      const double mean = sum[c] / count;
      const double variance = std::max(0.0, sum2[c] / count - mean * mean);
      means[static_cast<std::size_t>(4 * j) + c] = static_cast<float>(mean);
      deviations[static_cast<std::size_t>(4 * j) + c] = static_cast<float>(std::sqrt(variance));
    }
  }
  normalise(means.data(), static_cast<int>(means.size()));
  normalise(deviations.data(), static_cast<int>(deviations.size()));
  std::array<float, 8 * kLbdBands> out{};
  for (std::size_t j = 0; j < kLbdBands; ++j)
    for (std::size_t c = 0; c < 4; ++c) {
      out[8 * j + c] = std::min(kClip, means[4 * j + c]);
      out[8 * j + 4 + c] = std::min(kClip, deviations[4 * j + c]);
    }
  normalise(out.data(), static_cast<int>(out.size()));
  return out;
}

LineDescriptor LineBandDescriber::describe(const Eigen::Vector2d& start,
                                           const Eigen::Vector2d& end) const {
  const std::array<float, 8 * kLbdBands> v = statistics(start, end);
  LineDescriptor descriptor;
  for (std::size_t p = 0; p < kPairs.size(); ++p) {
    const auto i = static_cast<std::size_t>(8 * kPairs[p][0]);
    const auto j = static_cast<std::size_t>(8 * kPairs[p][1]);
    std::uint8_t byte = 0;
    for (std::size_t c = 0; c < 8; ++c)
      if (v[i + c] > v[j + c]) byte = static_cast<std::uint8_t>(byte | (1u << c));
    descriptor.bytes[p] = byte;
  }
  return descriptor;
}

}  // namespace mcslam::features::detail
