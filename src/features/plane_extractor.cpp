#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>
#include <numbers>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/features/planes.hpp"

namespace mcslam::features {
namespace {

// A cell needs at least this fraction of its pixels with valid depth: sparse cells give poorly
// constrained planes, and holes in Kinect-like depth sit mostly at discontinuities.
constexpr double kMinValidFraction = 0.6;
// Cells thinner than this fraction of cell_size (the last row/column of cells when the image size
// is not a multiple of it) are not fitted; their pixels can still join a neighbouring plane.
constexpr double kMinCellSideFraction = 0.5;
// Two consecutive valid pixels of a cell whose depths differ by more than this many cell
// tolerances form a discontinuity (far above the noise, and above the per-pixel depth change of
// any plane not seen nearly edge-on).
constexpr float kJumpFactor = 4.0f;
// Pixels belong to a plane within kInlierSigmas times the typical distance of its cells' points
// to it, clamped to [kMinInlierFactor, kInlierFactor] cell tolerances (see set_inlier_factors).
constexpr double kInlierSigmas = 3.0;
constexpr double kMinInlierFactor = 0.3;
constexpr double kInlierFactor = 1.5;
// A pixel leaves its cell's plane for another one closer by this many of the own plane's noise
// levels (see Extraction::assign_pixels).
constexpr double kSliverSigmas = 1.0;
// Normals agree within merge_angle_deg plus this many standard deviations of their difference.
constexpr double kNormalSigmas = 3.0;
// A cell or region whose normal disagrees still joins a plane whose RMS distance to its points is
// within this many cell tolerances (see Extraction::fits_plane).
constexpr double kPointFitFactor = 0.5;
// Regions whose cells cover less than this fraction of the minimum plane area are dissolved before
// the pixel assignment (their pixels may then join a neighbouring plane), which rarely doubles a
// region.
constexpr double kMajorFraction = 0.5;
// Regions of at least this many cells have planes certain enough to compete for the pixels near
// them even when too small to be output: a pixel goes to the plane it fits best.
constexpr int kCompetitorCells = 3;
// During growth a region's plane is refitted when its point count has grown by this factor since
// the last fit (amortised: O(log n) fits per region).
constexpr double kRefitGrowth = 1.25;
// Labels are CV_8SC1: at most this many regions can hold pixels at once.
constexpr int kMaxMajorRegions = 127;

/// Point count, mean and centred scatter matrix (sum of (p - mean)(p - mean)^T) of a point set.
/// Sets combine exactly (Chan et al.'s pairwise update), without the cancellation of raw sums.
/// Also the normal equations of the plane in inverse depth (see fit_plane_inverse_depth).
struct Moments {
  double n = 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  /// Sums of q q^T and of q / z over the points, q = (x / z, y / z, 1).
  Eigen::Matrix3d inverse_lhs = Eigen::Matrix3d::Zero();
  Eigen::Vector3d inverse_rhs = Eigen::Vector3d::Zero();

  void add(const Moments& o) {
    if (o.n <= 0.0) return;
    const double total = n + o.n;
    const Eigen::Vector3d delta = o.mean - mean;
    scatter += o.scatter + (n * o.n / total) * delta * delta.transpose();
    mean += (o.n / total) * delta;
    n = total;
    inverse_lhs += o.inverse_lhs;
    inverse_rhs += o.inverse_rhs;
  }

  /// The inverse of add, for a subset o of the points (a few outliers: no cancellation issue).
  void remove(const Moments& o) {
    if (o.n <= 0.0) return;
    const double rest = n - o.n;
    if (rest <= 0.0) {
      *this = Moments{};
      return;
    }
    const Eigen::Vector3d rest_mean = (n * mean - o.n * o.mean) / rest;
    const Eigen::Vector3d delta = o.mean - rest_mean;
    scatter -= o.scatter + (rest * o.n / n) * delta * delta.transpose();
    mean = rest_mean;
    n = rest;
    inverse_lhs -= o.inverse_lhs;
    inverse_rhs -= o.inverse_rhs;
  }
};

/// Raw sums of points relative to a shift point close to them (the first point added), so that
/// the squares stay small and the scatter does not suffer from cancellation.
struct ShiftedSums {
  double x0 = 0.0, y0 = 0.0, z0 = 0.0;
  double n = 0.0;
  double sx = 0.0, sy = 0.0, sz = 0.0;
  double sxx = 0.0, sxy = 0.0, sxz = 0.0, syy = 0.0, syz = 0.0, szz = 0.0;

  double qxx = 0.0, qxy = 0.0, qx = 0.0, qyy = 0.0, qy = 0.0, qxw = 0.0, qyw = 0.0, qw = 0.0;

  void add(double x, double y, double z) {
    const double w = 1.0 / z;
    const double xi = x * w, eta = y * w;
    qxx += xi * xi;
    qxy += xi * eta;
    qx += xi;
    qyy += eta * eta;
    qy += eta;
    qxw += xi * w;
    qyw += eta * w;
    qw += w;
    if (n == 0.0) {
      x0 = x;
      y0 = y;
      z0 = z;
    }
    x -= x0;
    y -= y0;
    z -= z0;
    n += 1.0;
    sx += x;
    sy += y;
    sz += z;
    sxx += x * x;
    sxy += x * y;
    sxz += x * z;
    syy += y * y;
    syz += y * z;
    szz += z * z;
  }

  Moments moments() const {
    Moments m;
    if (n <= 0.0) return m;
    m.n = n;
    const Eigen::Vector3d local_mean = Eigen::Vector3d(sx, sy, sz) / n;
    m.mean = Eigen::Vector3d(x0, y0, z0) + local_mean;
    Eigen::Matrix3d raw;
    raw << sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz;
    m.scatter = raw - n * local_mean * local_mean.transpose();
    m.inverse_lhs << qxx, qxy, qx, qxy, qyy, qy, qx, qy, n;
    m.inverse_rhs << qxw, qyw, qw;
    return m;
  }
};

struct PlaneFit {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double d = 0.0;
  double rms = 0.0;
  /// Standard deviation (rad) of the normal's direction: with n points spread s across the plane
  /// and sigma along the normal, about sigma / (s sqrt(n)) = sqrt(lambda0 / lambda1 / n).
  double normal_sigma = 0.0;

  double distance(double x, double y, double z) const {
    return normal.x() * x + normal.y() * y + normal.z() * z + d;
  }
};

/// Total least-squares plane of a point set (smallest-eigenvalue direction of the scatter), with
/// the normal towards the camera. `exact` selects the iterative solver (final planes) over the
/// closed-form one (cells and growing regions, where speed matters more than the last digits).
PlaneFit fit_plane(const Moments& m, bool exact) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  if (exact) {
    solver.compute(m.scatter);
  } else {
    solver.computeDirect(m.scatter);
  }
  PlaneFit fit;
  fit.normal = solver.eigenvectors().col(0).normalized();
  fit.d = -fit.normal.dot(m.mean);
  if (fit.d < 0.0) {
    fit.normal = -fit.normal;
    fit.d = -fit.d;
  }
  const double n = std::max(1.0, m.n);
  const double lambda0 = std::max(0.0, solver.eigenvalues()(0));
  const double lambda1 = std::max(solver.eigenvalues()(1), std::numeric_limits<double>::min());
  fit.rms = std::sqrt(lambda0 / n);
  fit.normal_sigma = std::min(1.0, std::sqrt(lambda0 / lambda1 / n));
  return fit;
}

/// The plane of a point set by least squares on inverse depth: n . p + d = 0 is
/// 1 / z = q . (-n / d) with q = (x / z, y / z, 1), linear in the pixel's ray. Depth noise lies
/// along the viewing rays, so on a plane seen obliquely total least squares is biased (the noise
/// adds scatter that tilts the smallest-eigenvalue direction towards the rays, by about
/// sigma^2 / spread^2 radians: a degree on a narrow strip of a distant wall); inverse depth has
/// the noise in the fitted variable only, and depth-camera noise (which grows with z^2) is about
/// constant in it, so ordinary least squares is unbiased there. The plane is then moved onto the
/// centroid. Falls back to total least squares when the system is degenerate.
PlaneFit fit_plane_inverse_depth(const Moments& m) {
  PlaneFit fit = fit_plane(m, true);
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(m.inverse_lhs);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return fit;
  const Eigen::Vector3d abc = ldlt.solve(m.inverse_rhs);
  const double norm = abc.norm();
  if (!(norm > 0.0) || !abc.allFinite()) return fit;
  Eigen::Vector3d normal = -abc / norm;
  double d = -normal.dot(m.mean);
  if (d < 0.0) {
    normal = -normal;
    d = -d;
  }
  fit.normal = normal;
  fit.d = d;
  fit.rms = std::sqrt(std::max(0.0, normal.dot(m.scatter * normal)) / std::max(1.0, m.n));
  return fit;
}

/// Sum of squared distances of a point set to the plane through `point` with unit normal n.
double squared_distance_sum(const Moments& m, const Eigen::Vector3d& n,
                            const Eigen::Vector3d& point) {
  const double offset = n.dot(m.mean - point);
  return n.dot(m.scatter * n) + m.n * offset * offset;
}

struct Cell {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  ///< pixel range [x0, x1) x [y0, y1)
  bool planar = false;
  Moments moments;
  PlaneFit fit;
  /// Normalised fit quality (rms / tolerance at the cell's depth): seeds are taken best first.
  double quality = 0.0;
  int region = -1;
};

struct Region {
  Moments moments;  ///< of its cells until the pixel assignment, then of its pixels
  PlaneFit fit;
  double fitted_n = 0.0;  ///< point count at the last fit during growth
  int cells = 0;          ///< 0 once merged into another region
  int major = -1;         ///< index among the regions that may receive pixels, -1 if none
  int plane = -1;         ///< index in the output, -1 when dropped
  /// Pixels within inlier_factor * cell tolerance of the plane belong to it (major regions).
  double inlier_factor = kInlierFactor;
  /// Typical RMS distance of its cells' points to its plane, in cell tolerances (major regions).
  double noise_ratio = 0.0;
};

int find_root(std::vector<int>& parent, int i) {
  while (parent[static_cast<std::size_t>(i)] != i) {
    const int up = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
    parent[static_cast<std::size_t>(i)] = up;  // path halving
    i = up;
  }
  return i;
}

/// Buffers of an extraction, kept from one call to the next: allocating and freeing them per
/// frame let the allocator hand their pages back to the system and fault them in again, which
/// cost ~2 ms per frame.
struct Buffers {
  std::vector<double> ray_x;
  std::vector<double> ray_y;
  std::vector<Cell> cells;
  std::vector<Region> regions;
  std::vector<int> majors;
  std::vector<int> row_min;
  std::vector<int> row_max;
  std::vector<float> column_terms;
};

/// Sums over a cell's valid points for its moments (relative to its first valid point) and for
/// its inverse-depth normal equations (q: sums of the pixel rays' products, w = 1 / z).
struct CellSums {
  double n = 0.0, sx = 0.0, sy = 0.0, sz = 0.0;
  double sxx = 0.0, sxy = 0.0, sxz = 0.0, syy = 0.0, syz = 0.0, szz = 0.0;
  double qxx = 0.0, qxy = 0.0, qx = 0.0, qyy = 0.0, qy = 0.0, qxw = 0.0, qyw = 0.0, qw = 0.0;
  bool jump = false;  ///< a depth discontinuity stopped the sums
};

/// The regions competing for the pixels of a cell: those of its 3x3 neighbourhood that are
/// major or large enough, each once, in scan order.
struct Competitors {
  std::array<int, 9> regions{};
  int count = 0;
  bool any_major = false;  ///< one of them may receive pixels
};

/// The per-call state of PlaneExtractor::extract.
class Extraction {
 public:
  Extraction(const PinholeCamera& camera, const PlaneOptions& options, const cv::Mat& depth,
             Buffers& buffers)
      : o_(options),
        depth_(depth),
        width_(depth.cols),
        height_(depth.rows),
        merge_angle_(options.merge_angle_deg * std::numbers::pi / 180.0),
        cos_merge_angle_(std::cos(merge_angle_)),
        ray_x_(buffers.ray_x),
        ray_y_(buffers.ray_y),
        cells_(buffers.cells),
        regions_(buffers.regions),
        majors_(buffers.majors),
        row_min_(buffers.row_min),
        row_max_(buffers.row_max),
        column_terms_(buffers.column_terms) {
    ray_x_.resize(static_cast<std::size_t>(width_));
    ray_y_.resize(static_cast<std::size_t>(height_));
    regions_.clear();
    majors_.clear();
    // Back-projection factors: unproject at z = 1 scales linearly with depth.
    for (int u = 0; u < width_; ++u)
      ray_x_[static_cast<std::size_t>(u)] = camera.unproject(Eigen::Vector2d(u, 0.0), 1.0).x();
    for (int v = 0; v < height_; ++v)
      ray_y_[static_cast<std::size_t>(v)] = camera.unproject(Eigen::Vector2d(0.0, v), 1.0).y();
  }

  PlaneExtraction run() {
    PlaneExtraction result;
    result.labels = cv::Mat(depth_.size(), CV_8SC1, cv::Scalar(-1));
    compute_cells();
    grow_regions();
    merge_regions();
    assign_pixels(result.labels);
    select_planes(result);
    if (!result.planes.empty()) finish_labels_and_hulls(result);
    return result;
  }

 private:
  static bool valid_depth(float z) {
    return z > 0.0f && z < std::numeric_limits<float>::infinity();  // false for NaN
  }
  double cell_tolerance(double z) const {
    return std::max(o_.cell_tolerance, o_.cell_tolerance_per_metre * z * z);
  }
  double merge_tolerance(double z) const {
    return o_.merge_distance + o_.cell_tolerance_per_metre * z * z;
  }
  // A distant noisy cell spans little more than its noise, so its normal is uncertain by several
  // degrees: the angle test allows for the uncertainty of both normals (zero on exact data).
  bool normals_agree(const PlaneFit& a, const PlaneFit& b) const {
    const double cos_angle = std::min(1.0, std::abs(a.normal.dot(b.normal)));
    if (cos_angle >= cos_merge_angle_) return true;
    const double slack = kNormalSigmas * std::sqrt(a.normal_sigma * a.normal_sigma +
                                                   b.normal_sigma * b.normal_sigma);
    return slack > 0.0 && std::acos(cos_angle) <= merge_angle_ + slack;
  }
  // Far away a cell spans little more than the depth noise, and its own normal means little;
  // such a cell (or small region) agrees with a plane that fits its points about as well as the
  // noise allows: RMS distance within half the cell tolerance (ss: sum of squared distances).
  bool fits_plane(const Moments& m, double ss) const {
    const double limit = kPointFitFactor * cell_tolerance(m.mean.z());
    return ss <= m.n * limit * limit;
  }
  /// Widens the extent of row v's pixels of a major region to [first, last] (no-op if empty).
  void extend_row(int major, int v, int first, int last) {
    if (last < first) return;
    const std::size_t at = static_cast<std::size_t>(major) * static_cast<std::size_t>(height_) +
                           static_cast<std::size_t>(v);
    row_min_[at] = std::min(row_min_[at], first);
    row_max_[at] = std::max(row_max_[at], last);
  }
  Cell& cell(int i) { return cells_[static_cast<std::size_t>(i)]; }
  Region& region(int i) { return regions_[static_cast<std::size_t>(i)]; }

  /// 1. Cells: moments of their valid points, plane fit, planarity.
  void compute_cells() {
    const int cs = o_.cell_size;
    ncx_ = (width_ + cs - 1) / cs;
    ncy_ = (height_ + cs - 1) / cs;
    const int min_side = std::max(2, static_cast<int>(std::ceil(kMinCellSideFraction * cs)));
    cells_.assign(static_cast<std::size_t>(ncx_ * ncy_), Cell{});
    std::vector<float> column_last(static_cast<std::size_t>(cs));
    for (int cy = 0; cy < ncy_; ++cy) {
      for (int cx = 0; cx < ncx_; ++cx) {
        Cell& c = cell(cy * ncx_ + cx);
        c.x0 = cx * cs;
        c.y0 = cy * cs;
        c.x1 = std::min(width_, c.x0 + cs);
        c.y1 = std::min(height_, c.y0 + cs);
        if (c.x1 - c.x0 < min_side || c.y1 - c.y0 < min_side) continue;
        compute_cell(c, column_last);
      }
    }
  }

  /// The point of the first valid pixel of a cell (row by row), false when it has none.
  bool first_valid_point(const Cell& c, Eigen::Vector3d& origin) const {
    for (int v = c.y0; v < c.y1; ++v) {
      const float* row = depth_.ptr<float>(v);
      for (int u = c.x0; u < c.x1; ++u) {
        if (!valid_depth(row[u])) continue;
        const double z0 = row[u];
        origin = Eigen::Vector3d(ray_x_[static_cast<std::size_t>(u)] * z0,
                                 ray_y_[static_cast<std::size_t>(v)] * z0, z0);
        return true;
      }
    }
    return false;
  }

  /// Sums over a cell's valid points: relative to `origin` for the moments (centring without a
  /// second pass), and of the inverse-depth normal equations; y / z is constant along a row, so
  /// its sums are formed once per row. Stops at a depth discontinuity (jump set).
  /// `column_last` is working space of at least the cell's width.
  CellSums cell_sums(const Cell& c, const Eigen::Vector3d& origin,
                     std::vector<float>& column_last) const {
    const auto tol_min = static_cast<float>(o_.cell_tolerance);
    const auto tol_z2 = static_cast<float>(o_.cell_tolerance_per_metre);
    const double x0 = origin.x(), y0 = origin.y(), z0 = origin.z();
    const int cw = c.x1 - c.x0;
    CellSums s;
    std::fill(column_last.begin(), column_last.begin() + cw, 0.0f);
    for (int v = c.y0; v < c.y1 && !s.jump; ++v) {
      const float* row = depth_.ptr<float>(v) + c.x0;
      const double* rx = ray_x_.data() + c.x0;
      const double y_per_z = ray_y_[static_cast<std::size_t>(v)];
      float row_last = 0.0f;
      double row_n = 0.0, row_x = 0.0, row_w = 0.0;
      for (int i = 0; i < cw; ++i) {
        const float z = row[i];
        if (!valid_depth(z)) continue;
        // Discontinuity: compare with the previous valid pixel of the row and of the column
        // (across holes too, since Kinect-like depth blanks both sides of an edge).
        float& above = column_last[static_cast<std::size_t>(i)];
        const float limit = kJumpFactor * std::max(tol_min, tol_z2 * z * z);
        if ((row_last > 0.0f && std::abs(z - row_last) > limit) ||
            (above > 0.0f && std::abs(z - above) > limit)) {
          s.jump = true;
          break;
        }
        row_last = z;
        above = z;
        const double x = rx[i] * z - x0;
        const double y = y_per_z * z - y0;
        const double dz = z - z0;
        s.n += 1.0;
        s.sx += x;
        s.sy += y;
        s.sz += dz;
        s.sxx += x * x;
        s.sxy += x * y;
        s.sxz += x * dz;
        s.syy += y * y;
        s.syz += y * dz;
        s.szz += dz * dz;
        const double w = 1.0f / z;  // float precision is ample here, and cheaper
        row_n += 1.0;
        row_x += rx[i];
        row_w += w;
        s.qxx += rx[i] * rx[i];
        s.qxw += rx[i] * w;
      }
      s.qx += row_x;
      s.qw += row_w;
      s.qxy += y_per_z * row_x;
      s.qy += y_per_z * row_n;
      s.qyy += y_per_z * y_per_z * row_n;
      s.qyw += y_per_z * row_w;
    }
    return s;
  }

  /// One cell's moments, plane fit and planarity; nothing when it has a depth discontinuity or
  /// too few valid points.
  void compute_cell(Cell& c, std::vector<float>& column_last) {
    Eigen::Vector3d origin;
    if (!first_valid_point(c, origin)) return;
    const CellSums s = cell_sums(c, origin, column_last);
    const int cw = c.x1 - c.x0;
    const int ch = c.y1 - c.y0;
    const double n = s.n;
    if (s.jump || n < kMinValidFraction * cw * ch || n < 6.0) return;
    const Eigen::Vector3d local_mean = Eigen::Vector3d(s.sx, s.sy, s.sz) / n;
    c.moments.n = n;
    c.moments.mean = origin + local_mean;
    c.moments.scatter << s.sxx, s.sxy, s.sxz, s.sxy, s.syy, s.syz, s.sxz, s.syz, s.szz;
    c.moments.scatter -= n * local_mean * local_mean.transpose();
    c.moments.inverse_lhs << s.qxx, s.qxy, s.qx, s.qxy, s.qyy, s.qy, s.qx, s.qy, n;
    c.moments.inverse_rhs << s.qxw, s.qyw, s.qw;
    c.fit = fit_plane(c.moments, false);
    const double tolerance = cell_tolerance(c.moments.mean.z());
    if (c.fit.rms > tolerance) return;
    c.planar = true;
    c.quality = c.fit.rms / tolerance;
  }

  /// 2. Region growing from the best-fitting cells first (breadth first over 4-neighbours): a
  /// cell joins a region when its centroid lies within the merge distance of the region's plane,
  /// its normal agrees (or, see fits_plane, the region's plane fits its points), and the merged
  /// points stay within max_fit_rms of that plane. (A single cell's own plane is too uncertain to
  /// extrapolate to a far region centroid, so the reverse distance is only tested between
  /// regions.) The region's plane is refitted as it grows.
  void grow_regions() {
    std::vector<std::pair<double, int>> seeds;  // (quality, cell): ties by cell index
    for (int i = 0; i < ncx_ * ncy_; ++i)
      if (cell(i).planar) seeds.emplace_back(cell(i).quality, i);
    std::sort(seeds.begin(), seeds.end());
    const double max_fit_ss = o_.max_fit_rms * o_.max_fit_rms;
    std::vector<int> tested(cells_.size(), -1);  // the last region that tested the cell
    std::vector<int> queue;
    queue.reserve(cells_.size());
    for (const auto& [quality, seed] : seeds) {
      if (cell(seed).region >= 0) continue;
      const int id = static_cast<int>(regions_.size());
      Region r;
      r.moments = cell(seed).moments;
      r.fit = cell(seed).fit;
      r.fitted_n = r.moments.n;
      r.cells = 1;
      cell(seed).region = id;
      tested[static_cast<std::size_t>(seed)] = id;
      queue.assign(1, seed);
      for (std::size_t head = 0; head < queue.size(); ++head) {
        const int at = queue[head];
        const int cx = at % ncx_, cy = at / ncx_;
        const std::array<int, 4> neighbours = {cx > 0 ? at - 1 : -1, cx + 1 < ncx_ ? at + 1 : -1,
                                               cy > 0 ? at - ncx_ : -1,
                                               cy + 1 < ncy_ ? at + ncx_ : -1};
        for (int j : neighbours) {
          if (j < 0) continue;
          Cell& c = cell(j);
          if (!c.planar || c.region >= 0 || tested[static_cast<std::size_t>(j)] == id) continue;
          tested[static_cast<std::size_t>(j)] = id;
          const Eigen::Vector3d& n = r.fit.normal;
          if (std::abs(n.dot(c.moments.mean) + r.fit.d) > merge_tolerance(c.moments.mean.z()))
            continue;
          const Eigen::Vector3d on_plane = -r.fit.d * n;
          const double cell_ss = squared_distance_sum(c.moments, n, on_plane);
          if (!normals_agree(r.fit, c.fit) && !fits_plane(c.moments, cell_ss)) continue;
          const double ss = squared_distance_sum(r.moments, n, on_plane) + cell_ss;
          if (ss > max_fit_ss * (r.moments.n + c.moments.n)) continue;
          r.moments.add(c.moments);
          ++r.cells;
          c.region = id;
          queue.push_back(j);
          if (r.moments.n >= kRefitGrowth * r.fitted_n) {
            r.fit = fit_plane(r.moments, false);
            r.fitted_n = r.moments.n;
          }
        }
      }
      r.fit = fit_plane(r.moments, false);
      regions_.push_back(r);
    }
  }

  /// 3. Merges neighbouring regions whose planes agree both ways (growth order can split a
  /// surface, e.g. when a noisy seed grabbed part of it before a better one).
  void merge_regions() {
    std::vector<std::pair<int, int>> pairs;
    for (int i = 0; i < ncx_ * ncy_; ++i) {
      const int a = cell(i).region;
      if (a < 0) continue;
      const int right = i % ncx_ + 1 < ncx_ ? cell(i + 1).region : -1;
      const int below = i + ncx_ < ncx_ * ncy_ ? cell(i + ncx_).region : -1;
      for (int b : {right, below})
        if (b >= 0 && b != a) pairs.emplace_back(std::min(a, b), std::max(a, b));
    }
    std::sort(pairs.begin(), pairs.end());
    pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
    std::vector<int> parent(regions_.size());
    std::iota(parent.begin(), parent.end(), 0);
    for (const auto& [first, second] : pairs) {
      // The lower index (the better seed) survives; pairs are visited in sorted order, so the
      // result is deterministic.
      const int a = std::min(find_root(parent, first), find_root(parent, second));
      const int b = std::max(find_root(parent, first), find_root(parent, second));
      if (a == b) continue;
      Region& ra = region(a);
      Region& rb = region(b);
      if (!normals_agree(ra.fit, rb.fit)) {
        const Region& small = ra.moments.n < rb.moments.n ? ra : rb;
        const Region& large = ra.moments.n < rb.moments.n ? rb : ra;
        const double ss =
            squared_distance_sum(small.moments, large.fit.normal, -large.fit.d * large.fit.normal);
        if (!fits_plane(small.moments, ss)) continue;
      }
      const Eigen::Vector3d& ma = ra.moments.mean;
      const Eigen::Vector3d& mb = rb.moments.mean;
      if (std::abs(ra.fit.normal.dot(mb) + ra.fit.d) > merge_tolerance(mb.z()) ||
          std::abs(rb.fit.normal.dot(ma) + rb.fit.d) > merge_tolerance(ma.z()))
        continue;
      Moments merged = ra.moments;
      merged.add(rb.moments);
      const PlaneFit fit = fit_plane(merged, false);
      if (fit.rms > o_.max_fit_rms) continue;
      ra.moments = merged;
      ra.fit = fit;
      ra.cells += rb.cells;
      rb.cells = 0;
      parent[static_cast<std::size_t>(b)] = a;
    }
    for (Cell& c : cells_)
      if (c.region >= 0) c.region = find_root(parent, c.region);
  }

  /// 4. Pixels. Regions too small to become planes are dissolved; the others (major regions)
  /// collect pixels, each within its own inlier distance (set_inlier_factors). A pixel of a major
  /// region's cell stays with that region unless another plane around is closer by a margin of
  /// the region's noise level: a neighbouring plane must not take it merely because the pixel lies
  /// near the line where the two planes meet (behind occluding edges), but a sliver of another
  /// surface in a cell straddling a crease goes to that surface. Any other pixel of a cell next to
  /// a major region goes to the closest plane among the competing regions around its cell, if that
  /// is a major region's. So the cell-sized gaps at plane boundaries fill and dissolved regions
  /// are absorbed. The labels receive the major index; the regions' moments become those of their
  /// pixels.
  void assign_pixels(cv::Mat& labels) {
    select_majors();
    std::vector<Moments> pixels(majors_.size());
    std::array<ShiftedSums, 9> sums;
    for (int i = 0; i < ncx_ * ncy_; ++i) {
      const Cell& c = cell(i);
      const Competitors competing = competitors(i);
      if (!competing.any_major) continue;
      // The candidate index of the cell's own major region, -1 if none.
      int own = -1;
      if (c.planar && region(c.region).major >= 0)
        own = static_cast<int>(
            std::find(competing.regions.begin(), competing.regions.end(), c.region) -
            competing.regions.begin());

      if (competing.count == 1 && own == 0) {
        assign_inner_cell(c, labels, pixels[static_cast<std::size_t>(region(c.region).major)],
                          sums[0]);
        continue;
      }
      assign_contested_cell(c, competing, own, labels, sums);
      for (int k = 0; k < competing.count; ++k) {
        const Region& reg = region(competing.regions[static_cast<std::size_t>(k)]);
        if (reg.major >= 0)
          pixels[static_cast<std::size_t>(reg.major)].add(
              sums[static_cast<std::size_t>(k)].moments());
      }
    }
    for (std::size_t k = 0; k < majors_.size(); ++k) region(majors_[k]).moments = pixels[k];
  }

  /// The major regions (those large enough, the largest kMaxMajorRegions), their exact planes and
  /// inlier factors; clears the row extents of their pixels.
  void select_majors() {
    const double min_pixels = o_.min_area_fraction * width_ * height_;
    std::vector<int> majors;
    for (int r = 0; r < static_cast<int>(regions_.size()); ++r) {
      const Region& reg = region(r);
      if (reg.cells > 0 && reg.moments.n >= std::max(3.0, kMajorFraction * min_pixels))
        majors.push_back(r);
    }
    std::stable_sort(majors.begin(), majors.end(),
                     [this](int a, int b) { return region(a).moments.n > region(b).moments.n; });
    if (majors.size() > static_cast<std::size_t>(kMaxMajorRegions)) majors.resize(kMaxMajorRegions);
    majors_ = majors;
    for (std::size_t k = 0; k < majors_.size(); ++k) {
      Region& reg = region(majors_[k]);
      reg.major = static_cast<int>(k);
      reg.fit = fit_plane(reg.moments, true);
    }
    set_inlier_factors();
    row_min_.assign(majors_.size() * static_cast<std::size_t>(height_), width_);
    row_max_.assign(majors_.size() * static_cast<std::size_t>(height_), -1);
  }

  /// The regions competing for the pixels of cell i.
  Competitors competitors(int i) {
    const auto competes = [this](int r) {
      return r >= 0 && (region(r).major >= 0 || region(r).cells >= kCompetitorCells);
    };
    Competitors found;
    const int cx = i % ncx_, cy = i / ncx_;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = cx + dx, ny = cy + dy;
        if (nx < 0 || ny < 0 || nx >= ncx_ || ny >= ncy_) continue;
        const int r = cell(ny * ncx_ + nx).region;
        if (!competes(r)) continue;
        const auto listed = found.regions.begin() + found.count;
        if (std::find(found.regions.begin(), listed, r) != listed) continue;
        found.regions[static_cast<std::size_t>(found.count++)] = r;
        found.any_major = found.any_major || region(r).major >= 0;
      }
    }
    return found;
  }

  /// The pixels of a cell with several competing regions: each goes to the closest plane, the
  /// cell's own (candidate index `own`, -1 if none) keeping its inliers unless another plane is
  /// closer by a margin, when that plane is a major region's and the pixel its inlier. The sums
  /// of the pixels each candidate receives go to `sums` (by candidate index).
  void assign_contested_cell(const Cell& c, const Competitors& competing, int own, cv::Mat& labels,
                             std::array<ShiftedSums, 9>& sums) {
    const auto candidate = [&](int k) -> const Region& {
      return region(competing.regions[static_cast<std::size_t>(k)]);
    };
    for (int k = 0; k < competing.count; ++k) sums[static_cast<std::size_t>(k)] = ShiftedSums{};
    for (int v = c.y0; v < c.y1; ++v) {
      const float* row = depth_.ptr<float>(v);
      auto* label_row = labels.ptr<std::int8_t>(v);
      const double y_per_z = ray_y_[static_cast<std::size_t>(v)];
      for (int u = c.x0; u < c.x1; ++u) {
        const float z = row[u];
        if (!valid_depth(z)) continue;
        const double x = ray_x_[static_cast<std::size_t>(u)] * z;
        const double y = y_per_z * z;
        const double tolerance = cell_tolerance(z);
        // The closest competing plane other than the cell's own.
        int best = -1;
        double best_distance = std::numeric_limits<double>::infinity();
        for (int k = 0; k < competing.count; ++k) {
          if (k == own) continue;
          const double distance = std::abs(candidate(k).fit.distance(x, y, z));
          if (distance < best_distance) {  // ties: the first in scan order (deterministic)
            best_distance = distance;
            best = k;
          }
        }
        if (own >= 0) {
          // An inlier of the cell's own plane stays unless another plane is closer by a margin
          // of the own plane's noise level: then it is a sliver of the other surface.
          const Region& reg = candidate(own);
          const double distance = std::abs(reg.fit.distance(x, y, z));
          if (distance <= reg.inlier_factor * tolerance &&
              best_distance >= distance - kSliverSigmas * reg.noise_ratio * tolerance) {
            best = own;
            best_distance = distance;
          }
        }
        if (best < 0) continue;
        const Region& reg = candidate(best);
        if (reg.major < 0 || best_distance > reg.inlier_factor * tolerance) continue;
        label_row[u] = static_cast<std::int8_t>(reg.major);
        extend_row(reg.major, v, u, u);
        sums[static_cast<std::size_t>(best)].add(x, y, z);
      }
    }
  }

  /// The pixels of a cell inside its major region (no other plane around): the distance test
  /// only, branch-free in float per row (the hot loop). The cell's moments are taken as they are,
  /// less those of the (few) outliers, which are gathered in `outliers`.
  void assign_inner_cell(const Cell& c, cv::Mat& labels, Moments& pixels, ShiftedSums& outliers) {
    const Region& reg = region(c.region);
    const auto label = static_cast<std::int8_t>(reg.major);
    const int cw = c.x1 - c.x0;
    // distance = z * (nx * x / z + ny * y / z + nz) + d, the first term per column.
    column_terms_.resize(static_cast<std::size_t>(cw));
    for (int i = 0; i < cw; ++i)
      column_terms_[static_cast<std::size_t>(i)] =
          static_cast<float>(reg.fit.normal.x() * ray_x_[static_cast<std::size_t>(c.x0 + i)]);
    const auto d = static_cast<float>(reg.fit.d);
    const auto tol_min = static_cast<float>(reg.inlier_factor * o_.cell_tolerance);
    const auto tol_z2 = static_cast<float>(reg.inlier_factor * o_.cell_tolerance_per_metre);
    const float* terms = column_terms_.data();
    outliers = ShiftedSums{};
    for (int v = c.y0; v < c.y1; ++v) {
      const float* row = depth_.ptr<float>(v) + c.x0;
      auto* label_row = labels.ptr<std::int8_t>(v) + c.x0;
      const double y_per_z = ray_y_[static_cast<std::size_t>(v)];
      const auto row_term = static_cast<float>(reg.fit.normal.y() * y_per_z + reg.fit.normal.z());
      int valid = 0, inliers = 0;
      for (int i = 0; i < cw; ++i) {
        const float z = row[i];
        const bool ok = valid_depth(z);
        const float distance = z * (terms[i] + row_term) + d;
        const bool inlier = ok && std::abs(distance) <= std::max(tol_min, tol_z2 * z * z);
        label_row[i] = inlier ? label : label_row[i];
        valid += ok;
        inliers += inlier;
      }
      if (inliers > 0) {
        int first = 0, last = cw - 1;
        while (label_row[first] != label) ++first;
        while (label_row[last] != label) --last;
        extend_row(reg.major, v, c.x0 + first, c.x0 + last);
      }
      if (inliers == valid) continue;
      for (int i = 0; i < cw; ++i) {
        const float z = row[i];
        if (!valid_depth(z) || label_row[i] == label) continue;
        outliers.add(ray_x_[static_cast<std::size_t>(c.x0 + i)] * z, y_per_z * z, z);
      }
    }
    Moments inlier_moments = c.moments;
    inlier_moments.remove(outliers.moments());
    pixels.add(inlier_moments);
  }

  /// The inlier distance of every major region, in cell tolerances: a few times the typical RMS
  /// distance of its cells to its plane (median over cells, so that cells straddling a crease do
  /// not count), which adapts to the actual noise (and non-flatness) of the surface; clamped to
  /// [kMinInlierFactor, kInlierFactor]. On clean depth it is small, so the pixels of another
  /// surface near a crease are not taken. The plane is first refitted on the cells within that
  /// distance, for the same reason.
  void set_inlier_factors() {
    // Per major region: (cell RMS distance to the plane / tolerance, cell index), in cell order.
    std::vector<std::vector<std::pair<double, int>>> ratios(majors_.size());
    std::vector<double> scratch;
    for (int pass = 0; pass < 2; ++pass) {
      for (auto& r : ratios) r.clear();
      for (int i = 0; i < ncx_ * ncy_; ++i) {
        const Cell& c = cell(i);
        if (!c.planar || region(c.region).major < 0) continue;
        const Region& reg = region(c.region);
        const double ss =
            squared_distance_sum(c.moments, reg.fit.normal, -reg.fit.d * reg.fit.normal);
        ratios[static_cast<std::size_t>(reg.major)].emplace_back(
            std::sqrt(ss / c.moments.n) / cell_tolerance(c.moments.mean.z()), i);
      }
      for (std::size_t k = 0; k < majors_.size(); ++k) {
        if (ratios[k].empty()) continue;
        scratch.clear();
        for (const auto& [ratio, i] : ratios[k]) scratch.push_back(ratio);
        const auto middle = scratch.begin() + static_cast<std::ptrdiff_t>(scratch.size() / 2);
        std::nth_element(scratch.begin(), middle, scratch.end());
        Region& reg = region(majors_[k]);
        reg.noise_ratio = *middle;
        reg.inlier_factor = std::clamp(kInlierSigmas * *middle, kMinInlierFactor, kInlierFactor);
        if (pass > 0) continue;
        Moments inliers;
        for (const auto& [ratio, i] : ratios[k])
          if (ratio <= reg.inlier_factor) inliers.add(cell(i).moments);
        if (inliers.n >= 3.0) reg.fit = fit_plane(inliers, true);
      }
    }
  }

  /// 5. Final fits on the pixels, filters, largest first.
  void select_planes(PlaneExtraction& result) {
    const double min_pixels = std::max(3.0, o_.min_area_fraction * width_ * height_);
    std::vector<int> kept;
    for (int r : majors_) {
      Region& reg = region(r);
      if (reg.moments.n < min_pixels) continue;
      reg.fit = fit_plane_inverse_depth(reg.moments);
      if (reg.fit.rms > o_.max_fit_rms) continue;
      kept.push_back(r);
    }
    std::stable_sort(kept.begin(), kept.end(),
                     [this](int a, int b) { return region(a).moments.n > region(b).moments.n; });
    if (kept.size() > static_cast<std::size_t>(o_.max_planes)) kept.resize(o_.max_planes);
    for (int r : kept) {
      Region& reg = region(r);
      reg.plane = static_cast<int>(result.planes.size());
      PlaneFeature plane;
      plane.normal = reg.fit.normal;
      plane.d = reg.fit.d;
      plane.centroid = reg.moments.mean;
      plane.num_pixels = static_cast<int>(std::lround(reg.moments.n));
      plane.rms = reg.fit.rms;
      result.planes.push_back(plane);
    }
  }

  /// 6. Labels from major index to plane index; convex hulls in in-plane coordinates.
  void finish_labels_and_hulls(PlaneExtraction& result) {
    std::array<std::int8_t, 128> plane_of;
    plane_of.fill(-1);
    bool identity = true;
    for (int r : majors_) {
      plane_of[static_cast<std::size_t>(region(r).major)] =
          static_cast<std::int8_t>(region(r).plane);
      identity = identity && region(r).plane == region(r).major;
    }
    // Often every major region became the plane of the same index; else relabel.
    if (!identity) {
      for (int v = 0; v < height_; ++v) {
        auto* label_row = result.labels.ptr<std::int8_t>(v);
        for (int u = 0; u < width_; ++u)
          if (label_row[u] >= 0) label_row[u] = plane_of[static_cast<std::size_t>(label_row[u])];
      }
    }
    // The convex hull of a plane's points is the image of the hull of their pixels (a homography
    // keeps convexity in front of the camera), so only the extreme pixels of every row can be
    // hull vertices (up to the noise off the plane).
    const auto num_planes = result.planes.size();
    const auto h = static_cast<std::size_t>(height_);
    std::vector<std::size_t> major_of(num_planes);
    for (int r : majors_)
      if (region(r).plane >= 0)
        major_of[static_cast<std::size_t>(region(r).plane)] =
            static_cast<std::size_t>(region(r).major);
    // In-plane axes (e1, e2, normal) are right-handed, so counter-clockwise in 2D is
    // counter-clockwise seen from the normal side.
    std::vector<cv::Point2f> points;
    std::vector<cv::Point2f> hull;
    for (std::size_t k = 0; k < num_planes; ++k) {
      PlaneFeature& plane = result.planes[k];
      const Eigen::Vector3d e1 = plane.normal.unitOrthogonal();
      const Eigen::Vector3d e2 = plane.normal.cross(e1);
      points.clear();
      for (int v = 0; v < height_; ++v) {
        const std::size_t at = major_of[k] * h + static_cast<std::size_t>(v);
        if (row_max_[at] < 0) continue;
        for (int u : {row_min_[at], row_max_[at]}) {
          const double z = depth_.at<float>(v, u);
          const Eigen::Vector3d q = Eigen::Vector3d(ray_x_[static_cast<std::size_t>(u)] * z,
                                                    ray_y_[static_cast<std::size_t>(v)] * z, z) -
                                    plane.centroid;
          const cv::Point2f point(static_cast<float>(e1.dot(q)), static_cast<float>(e2.dot(q)));
          if (std::isfinite(point.x) && std::isfinite(point.y)) points.push_back(point);
        }
      }
      if (points.size() < 3) continue;
      cv::convexHull(points, hull, false, true);
      plane.hull.reserve(hull.size());
      // The centroid lies on the plane (it is the fit's mean), so these points do too.
      for (const cv::Point2f& p : hull) plane.hull.push_back(plane.centroid + p.x * e1 + p.y * e2);
    }
  }

  const PlaneOptions& o_;
  const cv::Mat& depth_;
  const int width_;
  const int height_;
  const double merge_angle_;
  const double cos_merge_angle_;
  std::vector<double>& ray_x_;
  std::vector<double>& ray_y_;
  int ncx_ = 0;
  int ncy_ = 0;
  std::vector<Cell>& cells_;
  std::vector<Region>& regions_;
  std::vector<int>& majors_;  ///< region index of each major index
  /// Per major index and image row: the first and last column of the region's pixels.
  std::vector<int>& row_min_;
  std::vector<int>& row_max_;
  std::vector<float>& column_terms_;  ///< scratch of assign_inner_cell
};

}  // namespace

struct PlaneExtractor::Workspace {
  std::mutex mutex;  // one extraction at a time uses the buffers
  Buffers buffers;
  cv::Mat sampled;  // the depth image at the pixel step
};

namespace {

/// Keeps the planes that are their own target (target[i] == i), largest first (stable), and
/// renumbers the labels: a pixel of plane i takes the new index of plane target[i]. Nothing to do
/// when every plane is its own target and they are already in order.
void renumber(const std::vector<int>& target, PlaneExtraction& result) {
  auto& planes = result.planes;
  std::vector<int> survivors;
  for (std::size_t i = 0; i < planes.size(); ++i)
    if (target[i] == static_cast<int>(i)) survivors.push_back(static_cast<int>(i));
  std::stable_sort(survivors.begin(), survivors.end(), [&](int x, int y) {
    return planes[static_cast<std::size_t>(x)].num_pixels >
           planes[static_cast<std::size_t>(y)].num_pixels;
  });
  if (survivors.size() == planes.size() && std::is_sorted(survivors.begin(), survivors.end()))
    return;
  std::vector<int> new_index(planes.size(), -1);
  std::vector<PlaneFeature> kept;
  for (int k : survivors) {
    new_index[static_cast<std::size_t>(k)] = static_cast<int>(kept.size());
    kept.push_back(std::move(planes[static_cast<std::size_t>(k)]));
  }
  std::array<std::int8_t, 256> lut;
  lut.fill(-1);
  for (std::size_t i = 0; i < target.size(); ++i)
    lut[static_cast<std::uint8_t>(static_cast<std::int8_t>(i))] =
        static_cast<std::int8_t>(new_index[static_cast<std::size_t>(target[i])]);
  for (int v = 0; v < result.labels.rows; ++v) {
    auto* row = result.labels.ptr<std::int8_t>(v);
    for (int u = 0; u < result.labels.cols; ++u)
      if (row[u] >= 0) row[u] = lut[static_cast<std::uint8_t>(row[u])];
  }
  planes = std::move(kept);
}

/// Merges planes that lie on one infinite plane (see PlaneOptions::coplanar_angle_deg) and
/// renumbers planes (largest first) and labels.
void merge_coplanar(const PlaneOptions& o, PlaneExtraction& result) {
  auto& planes = result.planes;
  const double cos_angle = std::cos(o.coplanar_angle_deg * std::numbers::pi / 180.0);
  std::vector<int> target(planes.size());
  std::iota(target.begin(), target.end(), 0);
  bool merged = false;
  for (std::size_t i = 0; i < planes.size(); ++i) {
    if (target[i] != static_cast<int>(i)) continue;
    for (std::size_t j = i + 1; j < planes.size(); ++j) {
      if (target[j] != static_cast<int>(j)) continue;
      PlaneFeature& a = planes[i];
      const PlaneFeature& b = planes[j];
      if (a.normal.dot(b.normal) < cos_angle) continue;
      if (std::abs(a.distance(b.centroid)) > o.coplanar_distance ||
          std::abs(b.distance(a.centroid)) > o.coplanar_distance)
        continue;
      const double wa = a.num_pixels, wb = b.num_pixels, w = wa + wb;
      std::vector<Eigen::Vector3d> corners = a.hull;
      corners.insert(corners.end(), b.hull.begin(), b.hull.end());
      a.normal = (wa * a.normal + wb * b.normal).normalized();
      a.centroid = (wa * a.centroid + wb * b.centroid) / w;
      a.d = -a.normal.dot(a.centroid);
      a.rms = std::sqrt((wa * a.rms * a.rms + wb * b.rms * b.rms) / w);
      a.num_pixels += b.num_pixels;
      a.hull = plane_hull(a.normal, a.d, corners);
      target[j] = static_cast<int>(i);
      merged = true;
    }
  }
  if (merged) renumber(target, result);
}

}  // namespace

std::vector<Eigen::Vector3d> plane_hull(const Eigen::Vector3d& normal, double d,
                                        const std::vector<Eigen::Vector3d>& points) {
  // An orthonormal basis (e1, e2) of the plane, and the plane's point closest to the origin.
  const Eigen::Vector3d helper =
      std::abs(normal.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d e1 = normal.cross(helper).normalized();
  const Eigen::Vector3d e2 = normal.cross(e1);
  const Eigen::Vector3d origin = -d * normal;
  std::vector<cv::Point2f> flat;
  flat.reserve(points.size());
  for (const auto& p : points)
    flat.emplace_back(static_cast<float>(e1.dot(p - origin)),
                      static_cast<float>(e2.dot(p - origin)));
  std::vector<cv::Point2f> hull;
  if (flat.size() >= 3)
    cv::convexHull(flat, hull, false, true);
  else
    hull = flat;
  std::vector<Eigen::Vector3d> out;
  out.reserve(hull.size());
  for (const auto& h : hull)
    out.push_back(origin + static_cast<double>(h.x) * e1 + static_cast<double>(h.y) * e2);
  return out;
}

int PlaneOptions::effective_pixel_step() const {
  if (pixel_step > 0) return pixel_step;
  return std::clamp(cell_size / 3, 1, 3);
}

std::optional<std::string> PlaneOptions::check() const {
  if (cell_size < 3 || cell_size > 100) return "planes.cell_size must be in [3, 100]";
  if (pixel_step < 0 || pixel_step > 4) return "planes.pixel_step must be in [0, 4] (0: auto)";
  if (cell_size / effective_pixel_step() < 3)
    return "planes.cell_size / planes.pixel_step must be at least 3 (pixels of a cell's side)";
  if (!std::isfinite(cell_tolerance) || cell_tolerance <= 0.0 || cell_tolerance > 1.0)
    return "planes.cell_tolerance must be in (0, 1] metres";
  if (!std::isfinite(cell_tolerance_per_metre) || cell_tolerance_per_metre < 0.0 ||
      cell_tolerance_per_metre > 1.0)
    return "planes.cell_tolerance_per_metre must be in [0, 1]";
  if (!std::isfinite(merge_angle_deg) || merge_angle_deg <= 0.0 || merge_angle_deg >= 90.0)
    return "planes.merge_angle_deg must be in (0, 90)";
  if (!std::isfinite(merge_distance) || merge_distance < 0.0 || merge_distance > 1.0)
    return "planes.merge_distance must be in [0, 1] metres";
  if (!std::isfinite(min_area_fraction) || min_area_fraction < 0.0 || min_area_fraction > 1.0)
    return "planes.min_area_fraction must be in [0, 1]";
  if (!std::isfinite(max_fit_rms) || max_fit_rms <= 0.0 || max_fit_rms > 1.0)
    return "planes.max_fit_rms must be in (0, 1] metres";
  // Labels are CV_8SC1, so plane indices must fit in a signed byte.
  if (max_planes < 1 || max_planes > 127) return "planes.max_planes must be in [1, 127]";
  if (!std::isfinite(coplanar_angle_deg) || coplanar_angle_deg < 0.0 || coplanar_angle_deg >= 90.0)
    return "planes.coplanar_angle_deg must be in [0, 90)";
  if (!std::isfinite(coplanar_distance) || coplanar_distance < 0.0 || coplanar_distance > 1.0)
    return "planes.coplanar_distance must be in [0, 1] metres";
  return std::nullopt;
}

namespace {

/// The labels of the full depth image from those of its samples (every step-th pixel of every
/// step-th row): a pixel takes, of the planes of the (up to) four samples around it, the one its
/// own point is closest to, when that point lies within the extractor's widest inlier band of it
/// (kInlierFactor cell tolerances); else none. A sample's label does not hold for its neighbours
/// unchecked: they may lack depth, or lie on a small object on the plane or across its edge.
/// Each plane's pixel count becomes that of the full image.
cv::Mat full_labels(const PinholeCamera& camera, const PlaneOptions& options, const cv::Mat& depth,
                    PlaneExtraction& result, int step) {
  cv::Mat labels(depth.size(), CV_8SC1, cv::Scalar(-1));
  for (PlaneFeature& plane : result.planes) plane.num_pixels = 0;
  if (result.planes.empty()) return labels;
  // Per plane (n, d) in float: distance = |z * n . ray + d| with ray = (x/z, y/z, 1).
  std::vector<std::array<float, 4>> hessian;
  for (const PlaneFeature& plane : result.planes)
    hessian.push_back({static_cast<float>(plane.normal.x()), static_cast<float>(plane.normal.y()),
                       static_cast<float>(plane.normal.z()), static_cast<float>(plane.d)});
  const cv::Mat& sampled = result.labels;
  // The sample columns left and right of each pixel column (the same one on a sample column).
  std::vector<int> left(static_cast<std::size_t>(depth.cols));
  std::vector<int> right(static_cast<std::size_t>(depth.cols));
  std::vector<float> ray_x(static_cast<std::size_t>(depth.cols));
  for (int u = 0; u < depth.cols; ++u) {
    const auto i = static_cast<std::size_t>(u);
    left[i] = std::min(u / step, sampled.cols - 1);
    right[i] = std::min(left[i] + (u % step != 0 ? 1 : 0), sampled.cols - 1);
    ray_x[i] = static_cast<float>(camera.unproject(Eigen::Vector2d(u, 0.0), 1.0).x());
  }
  const auto band_min = static_cast<float>(kInlierFactor * options.cell_tolerance);
  const auto band_z2 = static_cast<float>(kInlierFactor * options.cell_tolerance_per_metre);
  std::vector<int> counts(result.planes.size(), 0);
  for (int v = 0; v < depth.rows; ++v) {
    const auto ray_y = static_cast<float>(camera.unproject(Eigen::Vector2d(0.0, v), 1.0).y());
    const int sv0 = std::min(v / step, sampled.rows - 1);
    const int sv1 = std::min(sv0 + (v % step != 0 ? 1 : 0), sampled.rows - 1);
    const std::int8_t* above = sampled.ptr<std::int8_t>(sv0);
    const std::int8_t* below = sampled.ptr<std::int8_t>(sv1);
    const float* row = depth.ptr<float>(v);
    std::int8_t* out = labels.ptr<std::int8_t>(v);
    for (int u = 0; u < depth.cols; ++u) {
      const auto i = static_cast<std::size_t>(u);
      const std::array<std::int8_t, 4> around{above[left[i]], above[right[i]], below[left[i]],
                                              below[right[i]]};
      if ((around[0] & around[1] & around[2] & around[3]) < 0) continue;  // all -1
      const float z = row[u];
      if (!(z > 0.0f) || !(z < std::numeric_limits<float>::infinity())) continue;
      float best_distance = std::max(band_min, band_z2 * z * z);
      int best = -1;
      for (int k = 0; k < 4; ++k) {
        const int label = around[static_cast<std::size_t>(k)];
        if (label < 0 || label == best) continue;
        const std::array<float, 4>& n = hessian[static_cast<std::size_t>(label)];
        const float distance = std::abs(z * (n[0] * ray_x[i] + n[1] * ray_y + n[2]) + n[3]);
        if (distance <= best_distance) {
          best = label;
          best_distance = distance;
        }
      }
      if (best < 0) continue;
      out[u] = static_cast<std::int8_t>(best);
      ++counts[static_cast<std::size_t>(best)];
    }
  }
  for (std::size_t k = 0; k < counts.size(); ++k) result.planes[k].num_pixels = counts[k];
  return labels;
}

}  // namespace

PlaneExtractor::PlaneExtractor(const PinholeCamera& camera, const PlaneOptions& options)
    : camera_(camera), options_(options), workspace_(std::make_unique<Workspace>()) {
  if (auto problem = options_.check()) throw InputError(*problem);
  if (auto problem = camera_.check()) throw InputError("plane extractor camera: " + *problem);
}

PlaneExtraction PlaneExtractor::extract(const cv::Mat& depth, Labels labels) const {
  if (depth.empty()) return {};
  if (depth.type() != CV_32FC1 || depth.cols != camera_.width || depth.rows != camera_.height) {
    PlaneExtraction result;
    if (labels == Labels::kFull) result.labels = cv::Mat(depth.size(), CV_8SC1, cv::Scalar(-1));
    return result;
  }
  std::lock_guard<std::mutex> lock(workspace_->mutex);
  const int step = options_.effective_pixel_step();
  if (step == 1) {
    PlaneExtraction result = Extraction(camera_, options_, depth, workspace_->buffers).run();
    merge_coplanar(options_, result);
    // At full resolution the labels come with the final fits (assign_pixels) at no extra cost.
    if (labels == Labels::kNone) result.labels.release();
    return result;
  }
  // Every step-th pixel of every step-th row, as a camera whose pixels are step times larger
  // (pixel u of the sampled image is pixel step * u of the full one, so the principal point
  // scales with the focal length). Depths are taken, never averaged: an average across a depth
  // jump would be a point on neither surface.
  cv::Mat& sampled = workspace_->sampled;
  sampled.create((depth.rows + step - 1) / step, (depth.cols + step - 1) / step, CV_32FC1);
  for (int v = 0; v < sampled.rows; ++v) {
    const float* from = depth.ptr<float>(v * step);
    float* to = sampled.ptr<float>(v);
    for (int u = 0; u < sampled.cols; ++u) to[u] = from[u * step];
  }
  PinholeCamera camera = camera_;
  camera.fx /= step;
  camera.fy /= step;
  camera.cx /= step;
  camera.cy /= step;
  camera.width = sampled.cols;
  camera.height = sampled.rows;
  PlaneOptions options = options_;
  options.cell_size = options_.cell_size / step;
  PlaneExtraction result = Extraction(camera, options, sampled, workspace_->buffers).run();
  merge_coplanar(options, result);
  if (labels == Labels::kNone) {
    for (PlaneFeature& plane : result.planes) plane.num_pixels *= step * step;
    result.labels.release();
    return result;
  }
  result.labels = full_labels(camera_, options_, depth, result, step);
  // Largest first again: the full image's counts may order two planes of nearly equal size
  // the other way.
  std::vector<int> themselves(result.planes.size());
  std::iota(themselves.begin(), themselves.end(), 0);
  renumber(themselves, result);
  return result;
}

PlaneExtractor::~PlaneExtractor() = default;
PlaneExtractor::PlaneExtractor(PlaneExtractor&&) noexcept = default;
PlaneExtractor& PlaneExtractor::operator=(PlaneExtractor&&) noexcept = default;

}  // namespace mcslam::features
