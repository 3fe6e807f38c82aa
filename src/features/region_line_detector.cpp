#include "region_line_detector.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

namespace mcslam::features::detail {
namespace {

/// Two level-line directions are aligned when they differ by at most this angle: LSD's value,
/// for which a pixel is aligned by chance with probability p = 22.5 / 180 = 1/8.
constexpr double kAngleToleranceDeg = 22.5;
constexpr double kAlignedChance = kAngleToleranceDeg / 180.0;
/// Intensities are integers: a gradient is known to about this many grey levels. A pixel whose
/// gradient is below kQuantisation / sin(tolerance) has a direction that error can turn by more
/// than the tolerance, so it takes no part (LSD's rule).
constexpr double kQuantisation = 2.0;
/// A region whose rectangle is filled by fewer aligned pixels than this fraction is refined
/// (LSD's value): a curved edge or two edges meeting at a small angle fill it sparsely.
constexpr double kMinDensity = 0.7;
/// Gradient magnitudes are ordered in this many bins (LSD's pseudo-ordering): seeds are taken
/// from the strongest gradients first, and within a bin in raster order (deterministic).
constexpr int kBins = 1024;
/// Each shrinking step keeps the pixels within this fraction of the previous radius.
constexpr double kShrinkFactor = 0.75;

double squared_distance(double ax, double ay, double bx, double by) {
  return (ax - bx) * (ax - bx) + (ay - by) * (ay - by);
}

}  // namespace

void RegionLineDetector::compute_gradients(const cv::Mat& gray) {
  const int w = width_;
  const int h = height_;
  stride_ = w + 2;
  const std::size_t n = static_cast<std::size_t>(stride_) * static_cast<std::size_t>(h + 2);
  ux_.resize(n);
  uy_.resize(n);
  magnitude_.resize(n);
  state_.assign(n, kUndefined);
  defined_.clear();
  max_magnitude_ = 0.0f;
  // The gradient of the 2x2 block whose top-left pixel is (x, y): g = (gx, gy) / 2 with the
  // integers below, centred at (x + 0.5, y + 0.5). Its level-line direction (the edge's
  // direction) is g turned by +90 degrees, (-gy, gx) / |g|. The last row and column have none.
  const double threshold = kQuantisation / std::sin(kAngleToleranceDeg * std::numbers::pi / 180.0);
  const int threshold2 = static_cast<int>(std::floor(4.0 * threshold * threshold));
  for (int y = 0; y + 1 < h; ++y) {
    const std::uint8_t* r0 = gray.ptr<std::uint8_t>(y);
    const std::uint8_t* r1 = gray.ptr<std::uint8_t>(y + 1);
    const int row = index(0, y);
    for (int x = 0; x + 1 < w; ++x) {
      const int da = r1[x + 1] - r0[x];  // D - A
      const int bc = r0[x + 1] - r1[x];  // B - C
      const int gx = da + bc;
      const int gy = da - bc;
      const int g2 = gx * gx + gy * gy;
      if (g2 <= threshold2) continue;
      const float norm = std::sqrt(static_cast<float>(g2));
      const int i = row + x;
      const auto k = static_cast<std::size_t>(i);
      ux_[k] = static_cast<float>(-gy) / norm;
      uy_[k] = static_cast<float>(gx) / norm;
      magnitude_[k] = 0.5f * norm;
      max_magnitude_ = std::max(max_magnitude_, magnitude_[k]);
      state_[k] = kFree;
      defined_.push_back(i);
    }
  }
}

void RegionLineDetector::order_pixels() {
  order_.clear();
  if (!(max_magnitude_ > 0.0f)) return;
  const float coefficient = (kBins - 1) / max_magnitude_;
  bin_start_.assign(kBins + 1, 0);
  auto bin_of = [&](int i) {
    // Strongest first: bin 0 holds the largest magnitudes.
    return kBins - 1 -
           std::min(kBins - 1,
                    static_cast<int>(magnitude_[static_cast<std::size_t>(i)] * coefficient));
  };
  for (const int i : defined_) ++bin_start_[static_cast<std::size_t>(bin_of(i)) + 1];
  for (int b = 0; b < kBins; ++b)
    bin_start_[static_cast<std::size_t>(b) + 1] += bin_start_[static_cast<std::size_t>(b)];
  order_.resize(defined_.size());
  for (const int i : defined_) {
    int& slot = bin_start_[static_cast<std::size_t>(bin_of(i))];
    order_[static_cast<std::size_t>(slot++)] = i;
  }
}

void RegionLineDetector::grow(int seed, double cos_tolerance) {
  region_.clear();
  region_.push_back(seed);
  const auto s = static_cast<std::size_t>(seed);
  state_[s] = kUsed;
  double rx = ux_[s];
  double ry = uy_[s];
  double norm = 1.0;
  // The frame of undefined pixels around the image stops the growth at its border.
  const std::array<int, 8> neighbours{-stride_ - 1, -stride_, -stride_ + 1, -1, 1,
                                      stride_ - 1,  stride_,  stride_ + 1};
  for (std::size_t k = 0; k < region_.size(); ++k) {
    const int p = region_[k];
    for (const int offset : neighbours) {
      const auto q = static_cast<std::size_t>(p + offset);
      if (state_[q] != kFree) continue;
      // Aligned: the angle between the pixel's direction and the region's is within the
      // tolerance, i.e. their dot product is at least its cosine.
      if (ux_[q] * rx + uy_[q] * ry < cos_tolerance * norm) continue;
      state_[q] = kUsed;
      region_.push_back(static_cast<int>(q));
      rx += ux_[q];
      ry += uy_[q];
      norm = std::sqrt(rx * rx + ry * ry);
    }
  }
  region_x_ = rx;
  region_y_ = ry;
}

bool RegionLineDetector::fit_rect(Rect& rect) const {
  double sw = 0.0, sx = 0.0, sy = 0.0;
  for (const int p : region_) {
    const double w = magnitude_[static_cast<std::size_t>(p)];
    sw += w;
    sx += w * (x_of(p));
    sy += w * (y_of(p));
  }
  if (!(sw > 0.0)) return false;
  const double cx = sx / sw;
  const double cy = sy / sw;
  // The main axis of the magnitude-weighted scatter of the pixel positions.
  double sxx = 0.0, syy = 0.0, sxy = 0.0;
  for (const int p : region_) {
    const double w = magnitude_[static_cast<std::size_t>(p)];
    const double dx = x_of(p) - cx;
    const double dy = y_of(p) - cy;
    sxx += w * dx * dx;
    syy += w * dy * dy;
    sxy += w * dx * dy;
  }
  const double theta = 0.5 * std::atan2(2.0 * sxy, sxx - syy);
  double dx = std::cos(theta);
  double dy = std::sin(theta);
  if (dx * region_x_ + dy * region_y_ < 0.0) {
    dx = -dx;
    dy = -dy;
  }
  double l_min = 0.0, l_max = 0.0, w_min = 0.0, w_max = 0.0;
  for (const int p : region_) {
    const double ox = x_of(p) - cx;
    const double oy = y_of(p) - cy;
    const double l = ox * dx + oy * dy;
    const double w = -ox * dy + oy * dx;
    l_min = std::min(l_min, l);
    l_max = std::max(l_max, l);
    w_min = std::min(w_min, w);
    w_max = std::max(w_max, w);
  }
  rect.x1 = cx + l_min * dx;
  rect.y1 = cy + l_min * dy;
  rect.x2 = cx + l_max * dx;
  rect.y2 = cy + l_max * dy;
  rect.width = std::max(1.0, w_max - w_min);
  return true;
}

double RegionLineDetector::density(const Rect& rect) const {
  const double length = std::sqrt(squared_distance(rect.x1, rect.y1, rect.x2, rect.y2));
  return static_cast<double>(region_.size()) / (std::max(length, 1e-9) * rect.width);
}

bool RegionLineDetector::refine(Rect& rect) {
  if (density(rect) >= kMinDensity) return true;
  // A new tolerance from the spread of the directions within one rectangle width of the seed:
  // twice their standard deviation about the seed's direction.
  const int seed = region_.front();
  const auto s = static_cast<std::size_t>(seed);
  const double sx = x_of(seed);
  const double sy = y_of(seed);
  const double width2 = rect.width * rect.width;
  double sum = 0.0, sum2 = 0.0;
  int n = 0;
  for (const int p : region_) {
    const auto q = static_cast<std::size_t>(p);
    state_[q] = kFree;
    if (squared_distance(sx, sy, x_of(p), y_of(p)) >= width2) continue;
    const double cross = ux_[s] * uy_[q] - uy_[s] * ux_[q];
    const double dot = ux_[s] * ux_[q] + uy_[s] * uy_[q];
    const double d = std::atan2(cross, dot);
    sum += d;
    sum2 += d * d;
    ++n;
  }
  const double mean = sum / n;
  const double tolerance = 2.0 * std::sqrt(std::max(0.0, sum2 / n - mean * mean));
  // At a tolerance of half a turn or more every direction is aligned.
  grow(seed, tolerance >= std::numbers::pi ? -1.0 : std::cos(tolerance));
  if (region_.size() < 2) return false;
  if (!fit_rect(rect)) return false;
  if (density(rect) >= kMinDensity) return true;
  return shrink(rect);
}

bool RegionLineDetector::shrink(Rect& rect) {
  const int seed = region_.front();
  const double sx = x_of(seed);
  const double sy = y_of(seed);
  double radius2 = std::max(squared_distance(sx, sy, rect.x1, rect.y1),
                            squared_distance(sx, sy, rect.x2, rect.y2));
  while (density(rect) < kMinDensity) {
    radius2 *= kShrinkFactor * kShrinkFactor;
    std::size_t kept = 0;
    for (const int p : region_) {
      if (squared_distance(sx, sy, x_of(p), y_of(p)) <= radius2) {
        region_[kept++] = p;
      } else {
        state_[static_cast<std::size_t>(p)] = kFree;
      }
    }
    region_.resize(kept);
    if (region_.size() < 2) return false;
    if (!fit_rect(rect)) return false;
  }
  return true;
}

void RegionLineDetector::detect(const cv::Mat& gray, std::vector<cv::Vec4f>& segments) {
  segments.clear();
  if (gray.empty() || gray.type() != CV_8UC1 || gray.dims != 2 || gray.cols < 2 || gray.rows < 2)
    return;
  // Pixel indices (with the frame around the image) are ints.
  if ((static_cast<double>(gray.cols) + 2.0) * (static_cast<double>(gray.rows) + 2.0) >
      static_cast<double>(std::numeric_limits<int>::max()))
    return;
  width_ = gray.cols;
  height_ = gray.rows;
  compute_gradients(gray);
  order_pixels();
  // A region of n aligned pixels arises by chance with probability p^n, and an image holds
  // about 11 (w h)^(5/2) candidate rectangles (two endpoints, sqrt(w h) widths, 11 angle
  // tolerances in LSD's count); regions smaller than where the expected number of chance
  // regions falls below one are noise (LSD's minimal region size: 14 pixels at 256 x 192).
  const double tests = 2.5 * (std::log10(width_) + std::log10(height_)) + std::log10(11.0);
  const auto min_region = static_cast<std::size_t>(-tests / std::log10(kAlignedChance));
  const double cos_tolerance = std::cos(kAngleToleranceDeg * std::numbers::pi / 180.0);
  for (const int seed : order_) {
    if (state_[static_cast<std::size_t>(seed)] != kFree) continue;
    grow(seed, cos_tolerance);
    if (region_.size() < min_region) continue;
    Rect rect;
    if (!fit_rect(rect)) continue;
    if (!refine(rect)) continue;
    // The gradients are centred half a pixel right of and below their top-left pixel.
    segments.emplace_back(static_cast<float>(rect.x1 + 0.5), static_cast<float>(rect.y1 + 0.5),
                          static_cast<float>(rect.x2 + 0.5), static_cast<float>(rect.y2 + 0.5));
  }
}

}  // namespace mcslam::features::detail
