#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "mcslam/features/lines.hpp"

namespace mcslam::features {
namespace {

/// What the geometric tests need of an observed segment, computed once per segment.
struct ObservedGeometry {
  Eigen::Vector2d start = Eigen::Vector2d::Zero();
  Eigen::Vector2d direction = Eigen::Vector2d::UnitX();  // unit, start -> end
  Eigen::Vector2d midpoint = Eigen::Vector2d::Zero();
  double length = 0.0;
  bool valid = false;
};

ObservedGeometry observed_geometry(const LineFeature& observed) {
  ObservedGeometry g;
  g.start = observed.start.cast<double>();
  const Eigen::Vector2d end = observed.end.cast<double>();
  const Eigen::Vector2d d = end - g.start;
  g.length = d.norm();
  g.valid = g.start.allFinite() && end.allFinite() && g.length > 0.0;
  if (g.valid) g.direction = d / g.length;
  g.midpoint = 0.5 * (g.start + end);
  return g;
}

bool consistent(const PredictedLine& predicted, const ObservedGeometry& observed,
                const LineMatchCriteria& criteria, double min_abs_cos) {
  if (!observed.valid) return false;
  const Eigen::Vector2d dp = predicted.end - predicted.start;
  const double predicted_length = dp.norm();
  if (!std::isfinite(predicted_length) || !(predicted_length > 0.0)) return false;

  // Directions compared undirected: a projected map line has no reliable orientation.
  if (!(std::abs(dp.dot(observed.direction)) / predicted_length > min_abs_cos)) return false;

  // Signed distances to the observed infinite line: the normal is the direction turned by 90 deg.
  const Eigen::Vector2d normal(-observed.direction.y(), observed.direction.x());
  const double d_start = std::abs(normal.dot(predicted.start - observed.start));
  const double d_end = std::abs(normal.dot(predicted.end - observed.start));
  if (!(0.5 * (d_start + d_end) < criteria.max_distance)) return false;

  // Overlap of the two intervals along the observed line.
  const double t_start = observed.direction.dot(predicted.start - observed.start);
  const double t_end = observed.direction.dot(predicted.end - observed.start);
  const double lo = std::max(0.0, std::min(t_start, t_end));
  const double hi = std::min(observed.length, std::max(t_start, t_end));
  const double overlap = std::max(0.0, hi - lo);
  const double shorter = std::min(observed.length, predicted_length);
  return overlap >= criteria.min_overlap * shorter;
}

double min_abs_cos(const LineMatchCriteria& criteria) {
  return std::cos(criteria.max_angle_deg * std::numbers::pi / 180.0);
}

}  // namespace

bool line_geometry_consistent(const PredictedLine& predicted, const LineFeature& observed,
                              const LineMatchCriteria& criteria) {
  return consistent(predicted, observed_geometry(observed), criteria, min_abs_cos(criteria));
}

std::vector<LineMatch> match_lines(const std::vector<PredictedLine>& predicted,
                                   const std::vector<LineFeature>& observed,
                                   const LineMatchCriteria& criteria) {
  std::vector<LineMatch> matches;
  if (predicted.empty() || observed.empty()) return matches;
  std::vector<ObservedGeometry> geometry;
  geometry.reserve(observed.size());
  for (const LineFeature& o : observed) geometry.push_back(observed_geometry(o));
  const double cos_limit = min_abs_cos(criteria);

  // Spatial pre-filter that never rejects a consistent pair: with a positive overlap some point
  // of the predicted segment lies beside the observed one, at most 2 * max_distance from it
  // (its endpoint distances average below max_distance), so the midpoints are at most
  // (L_p + L_o) / 2 + 2 * max_distance apart. Without an overlap requirement there is no bound.
  const bool prefilter = criteria.min_overlap > 0.0 && std::isfinite(criteria.max_distance);

  // Best observed line per predicted one (ties: the lower observed index).
  std::vector<LineMatch> best_for_predicted;
  for (std::size_t i = 0; i < predicted.size(); ++i) {
    const PredictedLine& p = predicted[i];
    const Eigen::Vector2d p_mid = 0.5 * (p.start + p.end);
    const double p_half = 0.5 * (p.end - p.start).norm();
    int best = -1;
    int best_distance = std::numeric_limits<int>::max();
    for (std::size_t j = 0; j < observed.size(); ++j) {
      const ObservedGeometry& g = geometry[j];
      if (prefilter) {
        const double reach = p_half + 0.5 * g.length + 2.0 * criteria.max_distance;
        if (!((p_mid - g.midpoint).squaredNorm() <= reach * reach)) continue;
      }
      const int distance = hamming_distance(p.descriptor, observed[j].descriptor);
      if (distance > criteria.max_descriptor_distance || distance >= best_distance) continue;
      if (!consistent(p, g, criteria, cos_limit)) continue;
      best = static_cast<int>(j);
      best_distance = distance;
    }
    if (best >= 0) best_for_predicted.push_back({static_cast<int>(i), best, best_distance});
  }

  // Each observed line goes to the predicted line closest in descriptor (ties: the lower
  // predicted index, which comes first here).
  std::vector<int> owner(observed.size(), -1);
  for (std::size_t m = 0; m < best_for_predicted.size(); ++m) {
    const LineMatch& candidate = best_for_predicted[m];
    int& o = owner[static_cast<std::size_t>(candidate.observed)];
    if (o < 0 || candidate.distance < best_for_predicted[static_cast<std::size_t>(o)].distance)
      o = static_cast<int>(m);
  }
  for (std::size_t m = 0; m < best_for_predicted.size(); ++m) {
    if (owner[static_cast<std::size_t>(best_for_predicted[m].observed)] == static_cast<int>(m))
      matches.push_back(best_for_predicted[m]);
  }
  return matches;  // already sorted by predicted index
}

}  // namespace mcslam::features
