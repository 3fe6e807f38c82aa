#include "features/orb_pattern.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <random>
#include <vector>

namespace mcslam::features::detail {
namespace {

constexpr int kRadius = 15;
constexpr std::uint64_t kSeed = 0x6d63736c616d4f52ULL;  // "mcslamOR"
constexpr int kNumCandidates = 4096;
constexpr int kMinBaseline = 4;  // pixels between the two points of a test
constexpr int kImageSize = 512;
constexpr int kNumShapes = 12000;
constexpr double kMinLeafSize = 2.0;
constexpr double kMaxLeafSize = 80.0;
constexpr int kNoise = 4;
constexpr int kMaxTrainingPatches = 2048;
constexpr int kNumDirections = 32;

/// Uniform integer in [0, n) from the top bits of one draw (n small, bias negligible and,
/// above all, identical on every platform).
int uniform_int(std::mt19937_64& rng, int n) {
  return static_cast<int>(((rng() >> 32) * static_cast<std::uint64_t>(n)) >> 32);
}

struct GreyImage {
  int width = 0;
  int height = 0;
  std::vector<int> pixels;
  int& at(int x, int y) { return pixels[static_cast<std::size_t>(y * width + x)]; }
  int at(int x, int y) const { return pixels[static_cast<std::size_t>(y * width + x)]; }
};

/// Size from a power law p(r) ~ r^-3 on [rmin, rmax] (the scale-invariant "dead leaves" model
/// of natural images), using only correctly rounded operations (division, square root).
int leaf_size(std::mt19937_64& rng, double rmin, double rmax) {
  const double u = static_cast<double>(rng() >> 11) * 0x1p-53;
  const double a = 1.0 / (rmin * rmin);
  const double b = 1.0 / (rmax * rmax);
  return static_cast<int>(1.0 / std::sqrt(a - u * (a - b)));
}

/// A "dead leaves" texture: occluding discs, rectangles and triangles of random grey levels
/// with power-law sizes, plus pixel noise.
GreyImage synthetic_texture(std::mt19937_64& rng) {
  GreyImage img{kImageSize, kImageSize, std::vector<int>(kImageSize * kImageSize, 128)};
  const int last = kImageSize - 1;
  for (int s = 0; s < kNumShapes; ++s) {
    const int type = uniform_int(rng, 3);
    const int value = uniform_int(rng, 256);
    const int cx = uniform_int(rng, kImageSize + 40) - 20;
    const int cy = uniform_int(rng, kImageSize + 40) - 20;
    const int size = leaf_size(rng, kMinLeafSize, kMaxLeafSize);
    if (type == 0) {
      const int r = size;
      for (int y = std::max(0, cy - r); y <= std::min(last, cy + r); ++y)
        for (int x = std::max(0, cx - r); x <= std::min(last, cx + r); ++x)
          if ((x - cx) * (x - cx) + (y - cy) * (y - cy) <= r * r) img.at(x, y) = value;
    } else if (type == 1) {
      const int hw = 1 + uniform_int(rng, 2 * size);
      const int hh = 1 + uniform_int(rng, 2 * size);
      for (int y = std::max(0, cy - hh); y <= std::min(last, cy + hh); ++y)
        for (int x = std::max(0, cx - hw); x <= std::min(last, cx + hw); ++x) img.at(x, y) = value;
    } else {
      int vx[3];
      int vy[3];
      for (int i = 0; i < 3; ++i) {
        vx[i] = cx + uniform_int(rng, 4 * size + 1) - 2 * size;
        vy[i] = cy + uniform_int(rng, 4 * size + 1) - 2 * size;
      }
      const int area = (vx[1] - vx[0]) * (vy[2] - vy[0]) - (vy[1] - vy[0]) * (vx[2] - vx[0]);
      if (area == 0) continue;
      const int x0 = std::max(0, std::min({vx[0], vx[1], vx[2]}));
      const int x1 = std::min(last, std::max({vx[0], vx[1], vx[2]}));
      const int y0 = std::max(0, std::min({vy[0], vy[1], vy[2]}));
      const int y1 = std::min(last, std::max({vy[0], vy[1], vy[2]}));
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
          bool inside = true;
          for (int i = 0; i < 3 && inside; ++i) {
            const int j = (i + 1) % 3;
            const int edge = (vx[j] - vx[i]) * (y - vy[i]) - (vy[j] - vy[i]) * (x - vx[i]);
            inside = area > 0 ? edge >= 0 : edge <= 0;
          }
          if (inside) img.at(x, y) = value;
        }
      }
    }
  }
  for (int& p : img.pixels) {
    int noise = 0;
    for (int k = 0; k < 4; ++k) noise += uniform_int(rng, 2 * kNoise + 1) - kNoise;
    p = std::clamp(p + noise / 2, 0, 255);
  }
  return img;
}

/// Separable binomial smoothing [1 4 6 4 1] / 16 (variance 1 per pass), borders replicated.
GreyImage binomial_smooth(const GreyImage& src, int passes) {
  GreyImage img = src;
  GreyImage tmp = src;
  const int w = img.width;
  const int h = img.height;
  for (int pass = 0; pass < passes; ++pass) {
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        auto px = [&](int dx) { return img.at(std::clamp(x + dx, 0, w - 1), y); };
        tmp.at(x, y) = (px(-2) + 4 * px(-1) + 6 * px(0) + 4 * px(1) + px(2) + 8) >> 4;
      }
    }
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        auto px = [&](int dy) { return tmp.at(x, std::clamp(y + dy, 0, h - 1)); };
        img.at(x, y) = (px(-2) + 4 * px(-1) + 6 * px(0) + 4 * px(1) + px(2) + 8) >> 4;
      }
    }
  }
  return img;
}

struct TrainingPatch {
  int x = 0;
  int y = 0;
  int cos1024 = 1024;  // orientation as a rounded unit vector scaled by 1024
  int sin1024 = 0;
};

/// Corner patches of the texture with their quantised intensity-centroid orientation.
std::vector<TrainingPatch> training_patches(const GreyImage& img) {
  cv::Mat mat(img.height, img.width, CV_8UC1);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      mat.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(img.at(x, y));
  std::vector<cv::KeyPoint> corners;
  cv::FAST(mat, corners, 20, true);

  std::array<int, kNumDirections> dir_cos{};
  std::array<int, kNumDirections> dir_sin{};
  for (int k = 0; k < kNumDirections; ++k) {
    const double a = 2.0 * std::numbers::pi * k / kNumDirections;
    dir_cos[static_cast<std::size_t>(k)] = static_cast<int>(std::lround(1024.0 * std::cos(a)));
    dir_sin[static_cast<std::size_t>(k)] = static_cast<int>(std::lround(1024.0 * std::sin(a)));
  }
  const std::array<int, 16> umax = circle_half_widths();
  const int margin = kRadius + 8;

  std::vector<TrainingPatch> patches;
  for (const cv::KeyPoint& kp : corners) {
    const int x = static_cast<int>(kp.pt.x);
    const int y = static_cast<int>(kp.pt.y);
    if (x < margin || y < margin || x >= img.width - margin || y >= img.height - margin) continue;
    std::int64_t m10 = 0;
    std::int64_t m01 = 0;
    for (int v = -kRadius; v <= kRadius; ++v) {
      const int du = umax[static_cast<std::size_t>(std::abs(v))];
      for (int u = -du; u <= du; ++u) {
        const int value = img.at(x + u, y + v);
        m10 += u * value;
        m01 += v * value;
      }
    }
    std::size_t best = 0;
    std::int64_t best_dot = std::numeric_limits<std::int64_t>::min();
    for (std::size_t k = 0; k < kNumDirections; ++k) {
      const std::int64_t dot = m10 * dir_cos[k] + m01 * dir_sin[k];
      if (dot > best_dot) {
        best_dot = dot;
        best = k;
      }
    }
    patches.push_back({x, y, dir_cos[best], dir_sin[best]});
  }
  if (patches.size() > kMaxTrainingPatches) {
    std::vector<TrainingPatch> subset;
    subset.reserve(kMaxTrainingPatches);
    for (std::size_t i = 0; i < kMaxTrainingPatches; ++i)
      subset.push_back(patches[i * patches.size() / kMaxTrainingPatches]);
    patches.swap(subset);
  }
  return patches;
}

int rotate_round(int a, int b) {  // (a - b) / 1024, rounded half up (floor of a shift)
  return (a - b + 512) >> 10;
}

/// Candidate tests: pairs of points uniform in the circular patch, at least kMinBaseline apart
/// (very short tests flip with noise).
std::vector<TestPair> candidate_tests(std::mt19937_64& rng) {
  std::vector<TestPair> candidates;
  candidates.reserve(kNumCandidates);
  auto point = [&](int& x, int& y) {
    do {
      x = uniform_int(rng, 2 * kRadius + 1) - kRadius;
      y = uniform_int(rng, 2 * kRadius + 1) - kRadius;
    } while (x * x + y * y > kRadius * kRadius);
  };
  while (static_cast<int>(candidates.size()) < kNumCandidates) {
    TestPair t;
    point(t.x1, t.y1);
    point(t.x2, t.y2);
    const int dx = t.x1 - t.x2;
    const int dy = t.y1 - t.y2;
    if (dx * dx + dy * dy < kMinBaseline * kMinBaseline) continue;
    candidates.push_back(t);
  }
  return candidates;
}

/// Every candidate's outcome on every training patch, as bit vectors, and its count of ones.
struct Outcomes {
  std::size_t patches = 0;
  std::size_t words = 0;  // 64-bit words per candidate
  std::vector<std::uint64_t> bits;
  std::vector<std::int64_t> ones;

  /// Squared correlation of two candidates' outcomes (exact integers to the last division).
  double squared_correlation(std::size_t a, std::size_t b) const {
    const auto n = static_cast<std::int64_t>(patches);
    std::int64_t n11 = 0;
    for (std::size_t w = 0; w < words; ++w)
      n11 += std::popcount(bits[a * words + w] & bits[b * words + w]);
    const std::int64_t cov = n * n11 - ones[a] * ones[b];
    const std::int64_t var = (ones[a] * (n - ones[a])) * (ones[b] * (n - ones[b]));
    return var == 0 ? 0.0 : static_cast<double>(cov * cov) / static_cast<double>(var);
  }
};

Outcomes outcomes_of(const std::vector<TestPair>& candidates, std::mt19937_64& rng) {
  const GreyImage texture = synthetic_texture(rng);
  const std::vector<TrainingPatch> patches = training_patches(texture);
  const GreyImage smooth = binomial_smooth(texture, 4);  // sigma 2, like the descriptor's blur
  Outcomes out;
  out.patches = patches.size();
  out.words = (out.patches + 63) / 64;
  out.bits.assign(candidates.size() * out.words, 0);
  out.ones.assign(candidates.size(), 0);
  for (std::size_t c = 0; c < candidates.size(); ++c) {
    const TestPair& t = candidates[c];
    for (std::size_t p = 0; p < out.patches; ++p) {
      const TrainingPatch& tp = patches[p];
      const int ax = tp.x + rotate_round(tp.cos1024 * t.x1, tp.sin1024 * t.y1);
      const int ay = tp.y + rotate_round(tp.sin1024 * t.x1, -tp.cos1024 * t.y1);
      const int bx = tp.x + rotate_round(tp.cos1024 * t.x2, tp.sin1024 * t.y2);
      const int by = tp.y + rotate_round(tp.sin1024 * t.x2, -tp.cos1024 * t.y2);
      if (smooth.at(ax, ay) < smooth.at(bx, by)) {
        out.bits[c * out.words + p / 64] |= std::uint64_t{1} << (p % 64);
        ++out.ones[c];
      }
    }
  }
  return out;
}

/// Greedy selection (as for rBRIEF): tests with the most balanced outcome first; a test is
/// accepted when its outcome mean is within kMaxBias of 1/2 and its correlation with every
/// accepted test is at most k / 20, with k starting at 4 (0.2) and relaxed until 256 tests are
/// found. Correlations are ratios of exact integers, so the choice is platform-independent.
/// Returns the accepted candidates' indices (k = 20 accepts any test, so 256 are always found).
std::vector<std::size_t> select_tests(const Outcomes& outcomes) {
  const std::size_t count = outcomes.ones.size();
  const auto n = static_cast<std::int64_t>(outcomes.patches);
  const std::vector<std::int64_t>& ones = outcomes.ones;
  std::vector<std::size_t> order(count);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return std::abs(2 * ones[a] - n) < std::abs(2 * ones[b] - n);
  });
  std::vector<std::size_t> accepted;
  std::vector<bool> taken(count, false);
  // Per candidate: how many accepted tests it was compared with, and its largest corr^2 so far.
  std::vector<std::size_t> compared(count, 0);
  std::vector<double> max_corr2(count, 0.0);
  for (int k = 4; accepted.size() < 256 && k <= 20; ++k) {
    const double threshold = (k * k) / 400.0;
    for (std::size_t c : order) {
      if (accepted.size() == 256) break;
      if (taken[c]) continue;
      // |mean - 1/2| <= kMaxBias  <=>  |2 ones - n| * 25 <= 6 n  (kMaxBias = 0.12)
      if (k < 20 && 25 * std::abs(2 * ones[c] - n) > 6 * n) continue;
      while (max_corr2[c] <= threshold && compared[c] < accepted.size()) {
        max_corr2[c] =
            std::max(max_corr2[c], outcomes.squared_correlation(c, accepted[compared[c]]));
        ++compared[c];
      }
      if (max_corr2[c] <= threshold) {
        accepted.push_back(c);
        taken[c] = true;
      }
    }
  }
  return accepted;
}

std::array<TestPair, 256> generate_pattern() {
  std::mt19937_64 rng(kSeed);
  const std::vector<TestPair> candidates = candidate_tests(rng);
  const std::vector<std::size_t> accepted = select_tests(outcomes_of(candidates, rng));
  std::array<TestPair, 256> pattern{};
  for (std::size_t i = 0; i < 256; ++i) pattern[i] = candidates[accepted[i]];
  return pattern;
}

}  // namespace

std::array<int, 16> circle_half_widths() {
  std::array<int, 16> umax{};
  for (int v = 0; v <= kRadius; ++v) {
    int u = 0;
    while ((u + 1) * (u + 1) + v * v <= kRadius * kRadius + kRadius && u + 1 <= kRadius) ++u;
    umax[static_cast<std::size_t>(v)] = u;
  }
  return umax;
}

const std::array<TestPair, 256>& orb_test_pattern() {
  static const std::array<TestPair, 256> pattern = generate_pattern();
  return pattern;
}

}  // namespace mcslam::features::detail
