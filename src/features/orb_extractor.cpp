#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <numeric>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <queue>
#include <vector>

#include "features/orb_pattern.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/core/parallel.hpp"
#include "mcslam/features/orb.hpp"

namespace mcslam::features {
namespace {

constexpr int kHalfPatch = OrbExtractor::kHalfPatch;
constexpr int kBorder = OrbExtractor::kBorder;
// Orientation and descriptor patches never leave the level image, so no padding is needed: the
// descriptor's Gaussian blur extrapolates the image border itself (BORDER_REFLECT_101).
static_assert(kBorder > kHalfPatch, "patches must stay inside the level image");
constexpr int kFastRadius = 3;
constexpr int kCellSize = 30;

/// A FAST corner in level pixel coordinates.
struct Candidate {
  int x = 0;
  int y = 0;
  float response = 0.0f;
};

struct Level {
  cv::Mat image;
  /// Affine map of level pixel coordinates to level 0: x0 = ax * x + bx, y0 = ay * y + by
  /// (cv::resize maps pixel centres: x_prev = (x + 0.5) * w_prev / w - 0.5).
  double ax = 1.0;
  double bx = 0.0;
  double ay = 1.0;
  double by = 0.0;
  std::vector<Candidate> candidates;
  int quota = 0;
  std::vector<Keypoint> keypoints;
  std::vector<OrbDescriptor> descriptors;
};

/// FAST corners of one level inside [kBorder, w - kBorder) x [kBorder, h - kBorder), in a
/// grid of ~30x30 px cells: a cell keeps its corners at the main threshold, or, when it has
/// none, its corners at the minimum threshold. FAST runs once, at the minimum threshold: a
/// corner's score is the largest threshold at which it is still a corner, and weaker
/// neighbours cannot suppress a stronger corner, so the corners scoring >= fast_threshold are
/// exactly those FAST finds at fast_threshold.
void detect_corners(const cv::Mat& image, const OrbOptions& options,
                    std::vector<cv::KeyPoint>& scratch, std::vector<Candidate>& candidates) {
  candidates.clear();
  const int rw = image.cols - 2 * kBorder;
  const int rh = image.rows - 2 * kBorder;
  if (rw < 1 || rh < 1) return;
  // FAST looks at a radius of 3 pixels and reports corners at least 3 pixels inside the Mat
  // handed to it, so pass the region grown by 3 on every side (a view, no copy).
  const cv::Rect roi(kBorder - kFastRadius, kBorder - kFastRadius, rw + 2 * kFastRadius,
                     rh + 2 * kFastRadius);
  scratch.clear();
  cv::FAST(image(roi), scratch, options.min_fast_threshold, true);

  const int ncx = std::max(1, static_cast<int>(std::lround(double(rw) / kCellSize)));
  const int ncy = std::max(1, static_cast<int>(std::lround(double(rh) / kCellSize)));
  auto cell_of = [&](const cv::KeyPoint& kp) {
    // Cells split the region evenly: cell i spans [i * rw / ncx, (i + 1) * rw / ncx).
    const int x = static_cast<int>(kp.pt.x) - kFastRadius;
    const int y = static_cast<int>(kp.pt.y) - kFastRadius;
    const int i = std::min(ncx - 1, static_cast<int>(static_cast<long long>(x) * ncx / rw));
    const int j = std::min(ncy - 1, static_cast<int>(static_cast<long long>(y) * ncy / rh));
    return static_cast<std::size_t>(j * ncx + i);
  };
  const auto strong = static_cast<float>(options.fast_threshold);
  std::vector<unsigned char> has_strong(static_cast<std::size_t>(ncx * ncy), 0);
  for (const cv::KeyPoint& kp : scratch)
    if (kp.response >= strong) has_strong[cell_of(kp)] = 1;
  candidates.reserve(scratch.size());
  for (const cv::KeyPoint& kp : scratch) {
    if (kp.response < strong && has_strong[cell_of(kp)]) continue;
    candidates.push_back(
        {static_cast<int>(kp.pt.x) + roi.x, static_cast<int>(kp.pt.y) + roi.y, kp.response});
  }
}

struct Node {
  float x0 = 0.0f;
  float y0 = 0.0f;
  float x1 = 0.0f;
  float y1 = 0.0f;
  int begin = 0;  // range of the index array
  int end = 0;
  int count() const { return end - begin; }
  bool splittable() const { return end - begin > 1 && (x1 - x0 > 1.0f || y1 - y0 > 1.0f); }
};

/// Splits `node` into its non-empty quadrants (partitioning idx in place).
int split_node(const Node& node, const std::vector<Candidate>& cands, std::vector<int>& idx,
               std::array<Node, 4>& children) {
  const float xm = 0.5f * (node.x0 + node.x1);
  const float ym = 0.5f * (node.y0 + node.y1);
  auto first = idx.begin() + node.begin;
  auto last = idx.begin() + node.end;
  auto mid = std::partition(first, last, [&](int i) { return float(cands[i].y) < ym; });
  auto m1 = std::partition(first, mid, [&](int i) { return float(cands[i].x) < xm; });
  auto m2 = std::partition(mid, last, [&](int i) { return float(cands[i].x) < xm; });
  const int b = node.begin;
  const int i1 = b + static_cast<int>(m1 - first);
  const int im = b + static_cast<int>(mid - first);
  const int i2 = b + static_cast<int>(m2 - first);
  const std::array<Node, 4> quads{{{node.x0, node.y0, xm, ym, b, i1},
                                   {xm, node.y0, node.x1, ym, i1, im},
                                   {node.x0, ym, xm, node.y1, im, i2},
                                   {xm, ym, node.x1, node.y1, i2, node.end}}};
  int n = 0;
  for (const Node& q : quads)
    if (q.count() > 0) children[static_cast<std::size_t>(n++)] = q;
  return n;
}

/// Square-ish first nodes over the region, each holding the candidates inside it (their indices
/// laid out node by node in idx).
std::vector<Node> initial_nodes(const std::vector<Candidate>& cands, float x0, float y0, float x1,
                                float y1, std::vector<int>& idx) {
  const float w = x1 - x0;
  const float h = y1 - y0;
  const int nx = std::max(1, static_cast<int>(std::lround(w / h)));
  const int ny = std::max(1, static_cast<int>(std::lround(h / w)));
  std::vector<std::vector<int>> buckets(static_cast<std::size_t>(nx * ny));
  for (int i = 0; i < static_cast<int>(cands.size()); ++i) {
    const int bx = std::min(nx - 1, static_cast<int>((float(cands[i].x) - x0) / w * nx));
    const int by = std::min(ny - 1, static_cast<int>((float(cands[i].y) - y0) / h * ny));
    buckets[static_cast<std::size_t>(by * nx + bx)].push_back(i);
  }
  std::vector<Node> nodes;
  int pos = 0;
  for (int by = 0; by < ny; ++by) {
    for (int bx = 0; bx < nx; ++bx) {
      const auto& bucket = buckets[static_cast<std::size_t>(by * nx + bx)];
      if (bucket.empty()) continue;
      std::copy(bucket.begin(), bucket.end(), idx.begin() + pos);
      nodes.push_back({x0 + w * bx / nx, y0 + h * by / ny, x0 + w * (bx + 1) / nx,
                       y0 + h * (by + 1) / ny, pos, pos + static_cast<int>(bucket.size())});
      pos += static_cast<int>(bucket.size());
    }
  }
  return nodes;
}

/// The last round of splits: the most populated nodes first, until there are `quota` nodes (or
/// none can be split).
void split_most_populated(std::vector<Node>& nodes, const std::vector<Candidate>& cands,
                          std::vector<int>& idx, int quota) {
  std::array<Node, 4> children;
  auto less = [&](int a, int b) {
    const int ca = nodes[static_cast<std::size_t>(a)].count();
    const int cb = nodes[static_cast<std::size_t>(b)].count();
    return ca != cb ? ca < cb : a > b;
  };
  std::priority_queue<int, std::vector<int>, decltype(less)> heap(less);
  for (int i = 0; i < static_cast<int>(nodes.size()); ++i)
    if (nodes[static_cast<std::size_t>(i)].splittable()) heap.push(i);
  while (static_cast<int>(nodes.size()) < quota && !heap.empty()) {
    const int top = heap.top();
    heap.pop();
    const int k = split_node(nodes[static_cast<std::size_t>(top)], cands, idx, children);
    nodes[static_cast<std::size_t>(top)] = children[0];
    if (children[0].splittable()) heap.push(top);
    for (int c = 1; c < k; ++c) {
      nodes.push_back(children[static_cast<std::size_t>(c)]);
      if (children[static_cast<std::size_t>(c)].splittable())
        heap.push(static_cast<int>(nodes.size()) - 1);
    }
  }
}

/// Splits the nodes holding more than one corner, breadth first, until there are `quota` nodes.
void split_nodes(std::vector<Node>& nodes, const std::vector<Candidate>& cands,
                 std::vector<int>& idx, int quota) {
  std::array<Node, 4> children;
  std::vector<Node> next;
  while (static_cast<int>(nodes.size()) < quota) {
    int splittable = 0;
    for (const Node& n : nodes) splittable += n.splittable() ? 1 : 0;
    if (splittable == 0) return;
    if (static_cast<int>(nodes.size()) + 3 * splittable > quota) {
      split_most_populated(nodes, cands, idx, quota);
      return;
    }
    // A whole round of splits cannot overshoot the quota: split every node.
    next.clear();
    for (const Node& n : nodes) {
      if (!n.splittable()) {
        next.push_back(n);
        continue;
      }
      const int k = split_node(n, cands, idx, children);
      next.insert(next.end(), children.begin(), children.begin() + k);
    }
    nodes.swap(next);
  }
}

/// Keeps at most `quota` candidates spread evenly over the region by a quadtree: nodes holding
/// more than one corner are split (breadth first) until there are `quota` nodes; the strongest
/// corner of every node is kept.
std::vector<Candidate> distribute(const std::vector<Candidate>& cands, float x0, float y0, float x1,
                                  float y1, int quota) {
  if (quota <= 0 || cands.empty()) return {};
  if (static_cast<int>(cands.size()) <= quota) return cands;
  std::vector<int> idx(cands.size());
  std::iota(idx.begin(), idx.end(), 0);
  std::vector<Node> nodes = initial_nodes(cands, x0, y0, x1, y1, idx);
  split_nodes(nodes, cands, idx, quota);

  std::vector<Candidate> kept;
  kept.reserve(nodes.size());
  for (const Node& n : nodes) {
    int best = idx[static_cast<std::size_t>(n.begin)];
    for (int k = n.begin + 1; k < n.end; ++k) {
      const int i = idx[static_cast<std::size_t>(k)];
      if (cands[static_cast<std::size_t>(i)].response >
          cands[static_cast<std::size_t>(best)].response)
        best = i;
    }
    kept.push_back(cands[static_cast<std::size_t>(best)]);
  }
  if (static_cast<int>(kept.size()) > quota) {
    // The last splits may overshoot by up to 3 nodes: drop the weakest corners.
    std::stable_sort(kept.begin(), kept.end(), [](const Candidate& a, const Candidate& b) {
      return a.response > b.response;
    });
    kept.resize(static_cast<std::size_t>(quota));
  }
  return kept;
}

/// Intensity-centroid orientation (degrees, [0, 360)) of the circular patch around `center`.
float patch_orientation(const std::uint8_t* center, std::ptrdiff_t step,
                        const std::array<int, kHalfPatch + 1>& umax) {
  int m10 = 0;
  int m01 = 0;
  for (int u = -kHalfPatch; u <= kHalfPatch; ++u) m10 += u * center[u];
  for (int v = 1; v <= kHalfPatch; ++v) {
    const int du = umax[static_cast<std::size_t>(v)];
    const std::uint8_t* below = center + v * step;
    const std::uint8_t* above = center - v * step;
    int row_diff = 0;
    for (int u = -du; u <= du; ++u) {
      const int b = below[u];
      const int a = above[u];
      row_diff += b - a;
      m10 += u * (b + a);
    }
    m01 += v * row_diff;
  }
  float deg = static_cast<float>(std::atan2(double(m01), double(m10)) * (180.0 / std::numbers::pi));
  if (deg < 0.0f) deg += 360.0f;
  if (deg >= 360.0f) deg = 0.0f;
  return deg;
}

void compute_descriptor(const std::uint8_t* center, std::ptrdiff_t step, float angle_deg,
                        const std::array<std::array<float, 4>, 256>& pattern, OrbDescriptor& out) {
  const float a = angle_deg * static_cast<float>(std::numbers::pi / 180.0);
  const float c = std::cos(a);
  const float s = std::sin(a);
  auto sample = [&](float x, float y) {
    const int rx = cvRound(c * x - s * y);
    const int ry = cvRound(s * x + c * y);
    return center[ry * step + rx];
  };
  for (int byte = 0; byte < 32; ++byte) {
    unsigned value = 0;
    for (int bit = 0; bit < 8; ++bit) {
      const auto& t = pattern[static_cast<std::size_t>(8 * byte + bit)];
      value |= static_cast<unsigned>(sample(t[0], t[1]) < sample(t[2], t[3])) << bit;
    }
    out.bytes[static_cast<std::size_t>(byte)] = static_cast<std::uint8_t>(value);
  }
}

}  // namespace

std::optional<std::string> OrbOptions::check() const {
  if (num_features < 1 || num_features > 100000) return "orb.num_features must be in [1, 100000]";
  if (num_levels < 1 || num_levels > 16) return "orb.num_levels must be in [1, 16]";
  if (!std::isfinite(scale_factor) || scale_factor <= 1.0 || scale_factor > 4.0)
    return "orb.scale_factor must be in (1, 4]";
  if (fast_threshold < 1 || fast_threshold > 254) return "orb.fast_threshold must be in [1, 254]";
  if (min_fast_threshold < 1 || min_fast_threshold > fast_threshold)
    return "orb.min_fast_threshold must be in [1, orb.fast_threshold]";
  if (!(moving_density >= 0.0 && moving_density <= 1000.0))
    return "orb.moving_density must be in [0, 1000] (0: no limit)";
  return std::nullopt;
}

OrbExtractor::OrbExtractor(const OrbOptions& options) : options_(options) {
  if (auto problem = options_.check()) throw InputError(*problem);
  const auto levels = static_cast<std::size_t>(options_.num_levels);
  scale_factors_.resize(levels);
  inv_scale_factors_.resize(levels);
  level_sigma2_.resize(levels);
  inv_level_sigma2_.resize(levels);
  for (std::size_t l = 0; l < levels; ++l) {
    scale_factors_[l] = std::pow(options_.scale_factor, static_cast<double>(l));
    inv_scale_factors_[l] = 1.0 / scale_factors_[l];
    level_sigma2_[l] = scale_factors_[l] * scale_factors_[l];
    inv_level_sigma2_[l] = 1.0 / level_sigma2_[l];
  }

  // Quotas geometric in the inverse scale (proportional to the level's area^(1/2)).
  features_per_level_.assign(levels, 0);
  const double factor = 1.0 / options_.scale_factor;
  double desired = options_.num_features * (1.0 - factor) /
                   (1.0 - std::pow(factor, static_cast<double>(levels)));
  int assigned = 0;
  for (std::size_t l = 0; l + 1 < levels; ++l) {
    features_per_level_[l] =
        std::min(options_.num_features - assigned, static_cast<int>(std::lround(desired)));
    assigned += features_per_level_[l];
    desired *= factor;
  }
  features_per_level_[levels - 1] = std::max(0, options_.num_features - assigned);

  const std::array<int, 16> umax = detail::circle_half_widths();
  std::copy(umax.begin(), umax.end(), umax_.begin());
  const auto& tests = detail::orb_test_pattern();
  for (std::size_t i = 0; i < tests.size(); ++i) {
    pattern_[i] = {float(tests[i].x1), float(tests[i].y1), float(tests[i].x2), float(tests[i].y2)};
  }
}

namespace {

/// Keeps `quota` of a level's candidates spread evenly by distribute(), at most
/// round(share * quota) of them where `moving` (a level-0 mask) is set and the rest elsewhere;
/// a side with fewer corners than its part hands the remainder to the other side.
std::vector<Candidate> distribute_split(const std::vector<Candidate>& cands, const cv::Mat& moving,
                                        double ax, double bx, double ay, double by, double share,
                                        float x0, float y0, float x1, float y1, int quota) {
  if (moving.empty() || share >= 1.0) return distribute(cands, x0, y0, x1, y1, quota);
  std::vector<Candidate> inside, outside;
  for (const Candidate& c : cands) {
    const int u = std::clamp(static_cast<int>(std::lround(ax * c.x + bx)), 0, moving.cols - 1);
    const int v = std::clamp(static_cast<int>(std::lround(ay * c.y + by)), 0, moving.rows - 1);
    (moving.at<std::uint8_t>(v, u) ? inside : outside).push_back(c);
  }
  const int cap = static_cast<int>(std::lround(share * quota));
  int in_quota = std::min(static_cast<int>(inside.size()), cap);
  const int out_quota = std::min(static_cast<int>(outside.size()), quota - in_quota);
  in_quota = std::min(static_cast<int>(inside.size()), quota - out_quota);
  std::vector<Candidate> kept = distribute(outside, x0, y0, x1, y1, out_quota);
  const std::vector<Candidate> in_kept = distribute(inside, x0, y0, x1, y1, in_quota);
  kept.insert(kept.end(), in_kept.begin(), in_kept.end());
  return kept;
}

/// The share of the image inside the keypoint border where `mask` is set.
double covered_share(const cv::Mat& mask, int border) {
  const cv::Rect inner(border, border, mask.cols - 2 * border, mask.rows - 2 * border);
  if (mask.empty() || inner.width <= 0 || inner.height <= 0) return 0.0;
  return static_cast<double>(cv::countNonZero(mask(inner))) / static_cast<double>(inner.area());
}

/// Builds the pyramid: each level is a bilinear resize of the previous one. Levels too small to
/// hold a keypoint (and all after them) stay empty. Returns the number of levels used.
int build_pyramid(const cv::Mat& gray, const std::vector<double>& inv_scale_factors,
                  std::vector<Level>& levels) {
  int used_levels = 0;
  const int num_levels = static_cast<int>(levels.size());
  for (int l = 0; l < num_levels; ++l) {
    Level& level = levels[static_cast<std::size_t>(l)];
    if (l == 0) {
      level.image = gray;
    } else {
      const Level& prev = levels[static_cast<std::size_t>(l - 1)];
      const double inv_scale = inv_scale_factors[static_cast<std::size_t>(l)];
      const int w = static_cast<int>(std::lround(gray.cols * inv_scale));
      const int h = static_cast<int>(std::lround(gray.rows * inv_scale));
      if (w <= 2 * kBorder || h <= 2 * kBorder) break;
      cv::resize(prev.image, level.image, cv::Size(w, h), 0.0, 0.0, cv::INTER_LINEAR);
      const double rx = double(prev.image.cols) / w;
      const double ry = double(prev.image.rows) / h;
      level.ax = prev.ax * rx;
      level.bx = prev.ax * (0.5 * rx - 0.5) + prev.bx;
      level.ay = prev.ay * ry;
      level.by = prev.ay * (0.5 * ry - 0.5) + prev.by;
    }
    if (level.image.cols <= 2 * kBorder || level.image.rows <= 2 * kBorder) break;
    used_levels = l + 1;
  }
  return used_levels;
}

/// Sets each level's quota: its share of the features (features_per_level), at most its number
/// of corners; a level with fewer corners than its share hands the remainder to the levels that
/// have more, in proportion to their shares.
void assign_quotas(std::vector<Level>& levels, int used_levels,
                   const std::vector<int>& features_per_level) {
  int deficit = 0;
  for (std::size_t l = 0; l < levels.size(); ++l) {
    Level& level = levels[l];
    const int base = features_per_level[l];
    level.quota = std::min(base, static_cast<int>(level.candidates.size()));
    deficit += base - level.quota;
  }
  while (deficit > 0) {
    long long weight = 0;
    for (int l = 0; l < used_levels; ++l) {
      const Level& level = levels[static_cast<std::size_t>(l)];
      if (static_cast<int>(level.candidates.size()) > level.quota)
        weight += std::max(1, features_per_level[static_cast<std::size_t>(l)]);
    }
    if (weight == 0) break;
    int given = 0;
    for (int l = 0; l < used_levels && given < deficit; ++l) {
      Level& level = levels[static_cast<std::size_t>(l)];
      const int spare = static_cast<int>(level.candidates.size()) - level.quota;
      if (spare <= 0) continue;
      const long long w = std::max(1, features_per_level[static_cast<std::size_t>(l)]);
      const int share = std::max(1, static_cast<int>(deficit * w / weight));
      const int add = std::min({share, spare, deficit - given});
      level.quota += add;
      given += add;
    }
    deficit -= given;
  }
}

/// The keypoints (level-0 position, orientation) and descriptors (on the level image blurred
/// with a 7x7 Gaussian) of the corners `kept` on level l.
void describe_level(Level& level, int l, const std::vector<Candidate>& kept,
                    const std::array<int, kHalfPatch + 1>& umax,
                    const std::array<std::array<float, 4>, 256>& pattern) {
  const std::ptrdiff_t step = static_cast<std::ptrdiff_t>(level.image.step[0]);
  level.keypoints.resize(kept.size());
  for (std::size_t i = 0; i < kept.size(); ++i) {
    const Candidate& c = kept[i];
    Keypoint& kp = level.keypoints[i];
    kp.uv = Eigen::Vector2f(static_cast<float>(level.ax * c.x + level.bx),
                            static_cast<float>(level.ay * c.y + level.by));
    kp.level = l;
    kp.response = c.response;
    kp.angle_deg = patch_orientation(level.image.ptr<std::uint8_t>(c.y) + c.x, step, umax);
  }
  cv::Mat blurred;
  cv::GaussianBlur(level.image, blurred, cv::Size(7, 7), 2.0, 2.0,
                   cv::BORDER_REFLECT_101 | cv::BORDER_ISOLATED);
  const std::ptrdiff_t bstep = static_cast<std::ptrdiff_t>(blurred.step[0]);
  level.descriptors.resize(kept.size());
  for (std::size_t i = 0; i < kept.size(); ++i) {
    compute_descriptor(blurred.ptr<std::uint8_t>(kept[i].y) + kept[i].x, bstep,
                       level.keypoints[i].angle_deg, pattern, level.descriptors[i]);
  }
}

/// Every level's keypoints and descriptors, level by level.
OrbFeatures gather_levels(const std::vector<Level>& levels) {
  OrbFeatures result;
  std::size_t total = 0;
  for (const Level& level : levels) total += level.keypoints.size();
  result.keypoints.reserve(total);
  result.descriptors.reserve(total);
  for (const Level& level : levels) {
    result.keypoints.insert(result.keypoints.end(), level.keypoints.begin(), level.keypoints.end());
    result.descriptors.insert(result.descriptors.end(), level.descriptors.begin(),
                              level.descriptors.end());
  }
  return result;
}

}  // namespace

OrbFeatures OrbExtractor::extract(const cv::Mat& gray, const cv::Mat& moving_mask) const {
  if (gray.empty() || gray.type() != CV_8UC1) return OrbFeatures{};
  const cv::Mat moving =
      moving_mask.size() == gray.size() && moving_mask.type() == CV_8UC1 ? moving_mask : cv::Mat();
  std::vector<Level> levels(static_cast<std::size_t>(options_.num_levels));
  const int used_levels = build_pyramid(gray, inv_scale_factors_, levels);
  if (used_levels == 0) return OrbFeatures{};
  // The moving regions' share of each level's quota (the same share of every level's area).
  const double moving_share =
      options_.moving_density > 0.0
          ? std::min(1.0, options_.moving_density * covered_share(moving, kBorder))
          : 1.0;

  parallel_for(0, used_levels, [&](int first, int last) {
    std::vector<cv::KeyPoint> scratch;
    for (int l = first; l < last; ++l) {
      Level& level = levels[static_cast<std::size_t>(l)];
      detect_corners(level.image, options_, scratch, level.candidates);
    }
  });
  assign_quotas(levels, used_levels, features_per_level_);
  parallel_for(0, used_levels, [&](int first, int last) {
    for (int l = first; l < last; ++l) {
      Level& level = levels[static_cast<std::size_t>(l)];
      const std::vector<Candidate> kept = distribute_split(
          level.candidates, moving, level.ax, level.bx, level.ay, level.by, moving_share,
          float(kBorder), float(kBorder), float(level.image.cols - kBorder),
          float(level.image.rows - kBorder), level.quota);
      if (!kept.empty()) describe_level(level, l, kept, umax_, pattern_);
    }
  });
  return gather_levels(levels);
}

}  // namespace mcslam::features
