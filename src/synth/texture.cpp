#include "texture.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <string>

#include "random.hpp"

namespace mcslam::synth::detail {
namespace {

constexpr int kPadMultiple = 64;
constexpr int kShift = 3;  // sub-texel precision of the drawing calls
constexpr double kScale = 1 << kShift;
constexpr double kTwoPi = 6.283185307179586;

int padded_texels(double size_m) {
  const int n = std::max(1, static_cast<int>(std::ceil(size_m / kTexelSize)));
  return (n + kPadMultiple - 1) / kPadMultiple * kPadMultiple;
}

cv::Point fixed_point(double x, double y) {
  return {static_cast<int>(std::lround(x * kScale)), static_cast<int>(std::lround(y * kScale))};
}

/// A colour of the given grey level (BT.601 luma) with a random hue and saturation sat in [0, 1].
cv::Scalar colour_with_luma(double luma, double hue_deg, double sat) {
  // Fully saturated colour of this hue.
  const double h = std::fmod(hue_deg, 360.0) / 60.0;
  const double x = 1.0 - std::abs(std::fmod(h, 2.0) - 1.0);
  double r = 0, g = 0, b = 0;
  switch (static_cast<int>(h)) {
    case 0:
      r = 1, g = x;
      break;
    case 1:
      r = x, g = 1;
      break;
    case 2:
      g = 1, b = x;
      break;
    case 3:
      g = x, b = 1;
      break;
    case 4:
      r = x, b = 1;
      break;
    default:
      r = 1, b = x;
      break;
  }
  const double y = 0.299 * r + 0.587 * g + 0.114 * b;
  // Zero-luma chroma direction, scaled so that every channel stays in [0, 255].
  const std::array<double, 3> d{b - y, g - y, r - y};
  double k_max = 1e9;
  for (double c : d) {
    if (c > 1e-9) k_max = std::min(k_max, (255.0 - luma) / c);
    if (c < -1e-9) k_max = std::min(k_max, luma / -c);
  }
  const double k = sat * std::min(k_max, 255.0);
  return {luma + k * d[0], luma + k * d[1], luma + k * d[2]};
}

/// A random colour that is clearly darker or brighter than a mid-grey background.
cv::Scalar contrast_colour(Rng& rng, double palette_hue) {
  const double luma = rng.chance(0.5) ? rng.uniform(8.0, 75.0) : rng.uniform(175.0, 250.0);
  const double hue =
      rng.chance(0.6) ? palette_hue + rng.uniform(-40.0, 40.0) + 360.0 : rng.uniform(0.0, 360.0);
  const double sat = rng.chance(0.3) ? 0.0 : rng.uniform(0.2, 0.9);
  return colour_with_luma(luma, hue, sat);
}

/// Smooth noise in [-amplitude, amplitude] with features of about `cell` texels.
cv::Mat smooth_noise(int w, int h, double cell, double amplitude, Rng& rng) {
  const int sw = std::max(2, static_cast<int>(w / cell) + 2);
  const int sh = std::max(2, static_cast<int>(h / cell) + 2);
  cv::Mat small(sh, sw, CV_32F);
  for (int y = 0; y < sh; ++y)
    for (int x = 0; x < sw; ++x)
      small.at<float>(y, x) = static_cast<float>(rng.uniform(-amplitude, amplitude));
  cv::Mat big;
  cv::resize(small, big, cv::Size(w, h), 0, 0, cv::INTER_CUBIC);
  return big;
}

/// Base colour plus luminance noise (octaves of {cell, amplitude}, cells in texels) and a faint
/// colour drift. The noise is built at half resolution and upsampled bilinearly (cheap).
cv::Mat noisy_background(int w, int h, const cv::Scalar& base,
                         const std::vector<std::pair<double, double>>& octaves, double chroma,
                         Rng& rng) {
  const int hw = std::max(1, w / 2), hh = std::max(1, h / 2);
  cv::Mat lum(hh, hw, CV_32F, cv::Scalar(0));
  for (const auto& [cell, amplitude] : octaves)
    lum += smooth_noise(hw, hh, 0.5 * cell, amplitude, rng);
  std::vector<cv::Mat> channels(3);
  for (int c = 0; c < 3; ++c) {
    channels[c] = lum + base[c];
    if (chroma > 0.0) channels[c] += smooth_noise(hw, hh, 150.0, chroma, rng);
  }
  cv::Mat merged, half, out;
  cv::merge(channels, merged);
  merged.convertTo(half, CV_8UC3);
  cv::resize(half, out, cv::Size(w, h), 0, 0, cv::INTER_LINEAR);
  return out;
}

enum ShapeType { kRect, kRotRect, kDisc, kPolygon, kText, kChecker, kStroke, kRing, kShapeTypes };

void draw_rotated_rect(cv::Mat& img, double cx, double cy, double a, double b, double angle,
                       const cv::Scalar& colour) {
  const double c = std::cos(angle), s = std::sin(angle);
  std::array<cv::Point, 4> pts;
  const double sx[4] = {-a, a, a, -a};
  const double sy[4] = {-b, -b, b, b};
  for (int k = 0; k < 4; ++k)
    pts[k] = fixed_point(cx + c * sx[k] - s * sy[k], cy + s * sx[k] + c * sy[k]);
  cv::fillConvexPoly(img, pts.data(), 4, colour, cv::LINE_AA, kShift);
}

void draw_shape(cv::Mat& img, ShapeType type, double cx, double cy, double size, Rng& rng,
                double palette_hue) {
  const cv::Scalar colour = contrast_colour(rng, palette_hue);
  const double angle = rng.uniform(0.0, kTwoPi);
  switch (type) {
    case kRect: {
      const double a = 0.5 * size, b = a * rng.uniform(0.3, 1.0);
      if (rng.chance(0.5))
        draw_rotated_rect(img, cx, cy, a, b, 0.0, colour);
      else
        draw_rotated_rect(img, cx, cy, b, a, 0.0, colour);
      break;
    }
    case kRotRect:
      draw_rotated_rect(img, cx, cy, 0.5 * size, 0.5 * size * rng.uniform(0.25, 1.0), angle,
                        colour);
      break;
    case kDisc: {
      const double a = 0.5 * size, b = a * rng.uniform(0.5, 1.0);
      cv::ellipse(img, fixed_point(cx, cy),
                  cv::Size(static_cast<int>(a * kScale), static_cast<int>(b * kScale)),
                  angle * 180.0 / 3.141592653589793, 0.0, 360.0, colour, cv::FILLED, cv::LINE_AA,
                  kShift);
      break;
    }
    case kPolygon: {
      const int n = rng.integer(3, 7);
      std::vector<double> angles(n);
      for (double& a : angles) a = rng.uniform(0.0, kTwoPi);
      std::sort(angles.begin(), angles.end());
      std::vector<cv::Point> pts;
      for (double a : angles) {
        const double r = 0.5 * size * rng.uniform(0.35, 1.0);
        pts.push_back(fixed_point(cx + r * std::cos(a), cy + r * std::sin(a)));
      }
      const cv::Point* data = pts.data();
      const int count = n;
      cv::fillPoly(img, &data, &count, 1, colour, cv::LINE_AA, kShift);
      break;
    }
    case kText: {
      static constexpr char kChars[] = "ABCDEFGHJKLMNPQRSTUVWXYZ0123456789#%&";
      std::string text;
      const int n = rng.integer(1, 5);
      for (int k = 0; k < n; ++k) text += kChars[rng.integer(0, sizeof(kChars) - 2)];
      static constexpr int kFonts[] = {cv::FONT_HERSHEY_SIMPLEX, cv::FONT_HERSHEY_DUPLEX,
                                       cv::FONT_HERSHEY_COMPLEX, cv::FONT_HERSHEY_TRIPLEX,
                                       cv::FONT_HERSHEY_PLAIN};
      const int font = kFonts[rng.integer(0, 4)];
      const double scale = std::max(0.3, size / 22.0);
      const int thickness = std::max(1, static_cast<int>(scale * rng.uniform(1.0, 3.0)));
      int baseline = 0;
      const cv::Size ts = cv::getTextSize(text, font, scale, thickness, &baseline);
      cv::putText(
          img, text,
          cv::Point(static_cast<int>(cx - 0.5 * ts.width), static_cast<int>(cy + 0.5 * ts.height)),
          font, scale, colour, thickness, cv::LINE_AA);
      break;
    }
    case kChecker: {
      const int rows = rng.integer(2, 5), cols = rng.integer(2, 5);
      const double cell = size / std::max(rows, cols);
      const cv::Scalar other = contrast_colour(rng, palette_hue + 180.0);
      const double c = std::cos(angle), s = std::sin(angle);
      for (int i = 0; i < rows; ++i)
        for (int j = 0; j < cols; ++j) {
          const double lx = (j - 0.5 * (cols - 1)) * cell, ly = (i - 0.5 * (rows - 1)) * cell;
          draw_rotated_rect(img, cx + c * lx - s * ly, cy + s * lx + c * ly, 0.5 * cell, 0.5 * cell,
                            angle, ((i + j) % 2) ? colour : other);
        }
      break;
    }
    case kStroke: {
      const int n = rng.integer(2, 4);
      std::vector<cv::Point> pts;
      double x = cx, y = cy, a = angle;
      pts.push_back(fixed_point(x, y));
      for (int k = 0; k < n; ++k) {
        const double len = size * rng.uniform(0.3, 0.7);
        x += len * std::cos(a);
        y += len * std::sin(a);
        a += rng.uniform(0.5, 2.0) * (rng.chance(0.5) ? 1.0 : -1.0);
        pts.push_back(fixed_point(x, y));
      }
      const int thickness = std::max(2, static_cast<int>(size * rng.uniform(0.06, 0.15)));
      cv::polylines(img, pts, false, colour, thickness, cv::LINE_AA, kShift);
      break;
    }
    case kRing:
    default: {
      const int thickness = std::max(2, static_cast<int>(size * rng.uniform(0.08, 0.2)));
      cv::circle(img, fixed_point(cx, cy), static_cast<int>(0.4 * size * kScale), colour, thickness,
                 cv::LINE_AA, kShift);
      break;
    }
  }
}

cv::Mat rich_texture(int w, int h, double size_u, double size_v, SurfaceKind kind, Rng& rng) {
  const double palette_hue = rng.uniform(0.0, 360.0);
  const double base_luma = rng.uniform(105.0, 150.0);
  const cv::Scalar base = colour_with_luma(base_luma, palette_hue, rng.uniform(0.05, 0.35));
  cv::Mat img = noisy_background(w, h, base, {{5.0, 9.0}, {20.0, 12.0}, {90.0, 16.0}}, 10.0, rng);

  // Per-surface mix of shape types, so that surfaces look different from each other.
  std::array<double, kShapeTypes> weights{};
  double total = 0.0;
  for (double& wgt : weights) total += (wgt = rng.uniform(0.2, 1.0));

  const double area = size_u * size_v;
  double density = 70.0;  // shapes per square metre
  if (kind == SurfaceKind::kFloor) density = 60.0;
  if (kind == SurfaceKind::kCeiling) density = 40.0;
  if (kind == SurfaceKind::kBoxFace) density = 90.0;
  const double w_m = size_u / kTexelSize, h_m = size_v / kTexelSize;  // texels used

  // A few large shapes first (distinctive "posters"), then many small ones.
  const int big = static_cast<int>(std::ceil(area * 1.2));
  for (int k = 0; k < big; ++k) {
    const double size = rng.uniform(0.25, std::min(0.7, 0.8 * std::min(size_u, size_v)));
    draw_shape(img, rng.chance(0.5) ? kRotRect : (rng.chance(0.5) ? kDisc : kPolygon),
               rng.uniform(0.0, w_m), rng.uniform(0.0, h_m), size / kTexelSize, rng, palette_hue);
  }
  const int count = static_cast<int>(area * density) + 4;
  for (int k = 0; k < count; ++k) {
    double pick = rng.uniform(0.0, total);
    int type = 0;
    while (type + 1 < kShapeTypes && pick > weights[type]) pick -= weights[type++];
    const double size = rng.log_uniform(0.012, 0.18) / kTexelSize;
    draw_shape(img, static_cast<ShapeType>(type), rng.uniform(0.0, w_m), rng.uniform(0.0, h_m),
               size, rng, palette_hue);
  }
  return img;
}

cv::Mat low_texture(int w, int h, double size_u, double size_v, SurfaceKind kind, Rng& rng) {
  const double hue = rng.uniform(0.0, 360.0);
  double luma = rng.uniform(150.0, 200.0);
  if (kind == SurfaceKind::kFloor) luma = rng.uniform(90.0, 130.0);
  if (kind == SurfaceKind::kBoxFace) luma = rng.uniform(60.0, 200.0);
  const cv::Scalar base = colour_with_luma(luma, hue, rng.uniform(0.05, 0.3));
  cv::Mat img = noisy_background(w, h, base, {{250.0, 2.0}, {60.0, 1.0}}, 0.0, rng);
  if (kind == SurfaceKind::kBoxFace) return img;

  // Only a few large axis-aligned shapes: posters / a door on walls, a rug, ceiling lights.
  int count = rng.integer(1, 3);
  double lo = 0.4, hi = 1.1;
  if (kind == SurfaceKind::kFloor) count = 1, lo = 1.0, hi = 2.0;
  if (kind == SurfaceKind::kCeiling) count = rng.integer(1, 2), lo = 0.5, hi = 1.0;
  for (int k = 0; k < count; ++k) {
    const double a = 0.5 * std::min(rng.uniform(lo, hi), 0.8 * size_u) / kTexelSize;
    const double b = 0.5 * std::min(rng.uniform(lo, hi), 0.8 * size_v) / kTexelSize;
    const double cx = rng.uniform(a, size_u / kTexelSize - a);
    const double cy = rng.uniform(b, size_v / kTexelSize - b);
    const double shape_luma =
        std::clamp(luma + (rng.chance(0.5) ? 1.0 : -1.0) * rng.uniform(45.0, 80.0), 20.0, 240.0);
    draw_rotated_rect(img, cx, cy, a, b, 0.0,
                      colour_with_luma(shape_luma, rng.uniform(0.0, 360.0), rng.uniform(0.1, 0.5)));
  }
  return img;
}

}  // namespace

cv::Mat generate_texture_image(double size_u, double size_v, TextureLevel level, SurfaceKind kind,
                               std::uint64_t seed) {
  Rng rng(seed);
  const int w = padded_texels(size_u), h = padded_texels(size_v);
  if (level == TextureLevel::kLow) return low_texture(w, h, size_u, size_v, kind, rng);
  return rich_texture(w, h, size_u, size_v, kind, rng);
}

std::vector<cv::Mat> build_mips(const cv::Mat& level0) {
  std::vector<cv::Mat> levels{level0};
  while (levels.back().cols % 2 == 0 && levels.back().rows % 2 == 0 &&
         std::min(levels.back().cols, levels.back().rows) >= 16) {
    cv::Mat next;
    cv::resize(levels.back(), next, cv::Size(levels.back().cols / 2, levels.back().rows / 2), 0, 0,
               cv::INTER_AREA);
    levels.push_back(next);
  }
  return levels;
}

}  // namespace mcslam::synth::detail
