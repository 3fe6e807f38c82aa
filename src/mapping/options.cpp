#include "mcslam/mapping/options.hpp"

#include <algorithm>
#include <cmath>

namespace mcslam::mapping {

int OccupancyOptions::effective_pixel_step(const PinholeCamera& camera) const {
  if (pixel_step > 0) return pixel_step;
  const double step = std::floor(resolution * camera.fx / (2.0 * max_range));
  return std::clamp(static_cast<int>(step), 1, 64);
}

double OccupancyOptions::effective_tail_yield_ratio() const {
  if (tail_yield_ratio >= 0.0) return tail_yield_ratio;
  const double sigma = depth_sigma(max_range);
  if (!(sigma > 0.0)) return 0.0;  // exact depth: no tail
  const auto tail = [](double x) { return 0.5 * std::erfc(x / std::sqrt(2.0)); };
  const double a = resolution / (2.0 * sigma);
  return (tail(a) - tail(3.0 * a)) / (1.0 - 2.0 * tail(a));
}

namespace {

std::optional<std::string> check_geometry(const OccupancyOptions& o) {
  if (!(o.max_range > 0.0) || !std::isfinite(o.max_range))
    return "mapping.max_range must be > 0 (metres)";
  if (!(o.resolution > 0.0)) return "mapping.resolution must be > 0 (metres)";
  if (o.resolution < 0.005)
    return "mapping.resolution must be >= 0.005 m (finer than the depth noise at 2 m)";
  if (o.resolution > o.max_range / 4.0)
    return "mapping.resolution must be <= mapping.max_range / 4 (a voxel larger than a quarter of "
           "the depth range maps nothing)";
  if (!(o.depth_noise_k >= 0.0) || o.depth_sigma(o.max_range) >= o.max_range / 4.0)
    return "mapping.depth_noise_k must be >= 0 and leave sigma_z at mapping.max_range below a "
           "quarter of the range";
  if (!(o.free_margin_sigmas >= 0.0) || o.free_margin_sigmas > 10.0)
    return "mapping.free_margin_sigmas must be in [0, 10]";
  if (!(o.spread_yield_ratio >= 0.0) || o.spread_yield_ratio > 1000.0)
    return "mapping.spread_yield_ratio must be in [0, 1000]";
  if (!std::isfinite(o.tail_yield_ratio) || o.tail_yield_ratio > 1000.0)
    return "mapping.tail_yield_ratio must be finite and at most 1000 (negative: from the noise "
           "model)";
  if (o.pixel_step < 0 || o.pixel_step > 64)
    return "mapping.pixel_step must be in [0, 64] (0: auto)";
  if (o.mask_dilation_px < 0 || o.mask_dilation_px > 50)
    return "mapping.mask_dilation_px must be in [0, 50] (pixels)";
  if (o.niceness < 0 || o.niceness > 19) return "mapping.niceness must be in [0, 19]";
  if (o.rebuild_threads < 1 || o.rebuild_threads > 16)
    return "mapping.rebuild_threads must be in [1, 16]";
  if (o.integration != "auto" && o.integration != "live" && o.integration != "at_end")
    return "mapping.integration must be auto, live or at_end, not \"" + o.integration + "\"";
  if (!(o.localize_view_period >= 0.0 && o.localize_view_period <= 3600.0))
    return "mapping.localize_view_period must be in [0, 3600] (seconds)";
  return std::nullopt;
}

std::optional<std::string> check_probabilities(const OccupancyOptions& o) {
  if (!(o.prob_hit > 0.5 && o.prob_hit < 1.0)) return "mapping.prob_hit must be in (0.5, 1)";
  if (!(o.prob_miss > 0.0 && o.prob_miss < 0.5)) return "mapping.prob_miss must be in (0, 0.5)";
  if (!(o.prob_occupied > 0.0 && o.prob_occupied < 1.0))
    return "mapping.prob_occupied must be in (0, 1)";
  if (!(o.clamp_min > 0.0 && o.clamp_min < o.prob_occupied))
    return "mapping.clamp_min must be in (0, mapping.prob_occupied)";
  if (!(o.clamp_max > o.prob_occupied && o.clamp_max < 1.0))
    return "mapping.clamp_max must be in (mapping.prob_occupied, 1)";
  return std::nullopt;
}

}  // namespace

std::optional<std::string> OccupancyOptions::check() const {
  if (auto e = check_geometry(*this)) return e;
  if (auto e = check_probabilities(*this)) return e;
  if (!std::isfinite(band_min) || !std::isfinite(band_max))
    return "mapping.band_min and mapping.band_max must be finite (metres above the floor)";
  if (!(band_max > band_min))
    return "mapping.band_min must be below mapping.band_max (the height band is upside down)";
  if (!(band_max > 0.0)) return "mapping.band_max must be > 0 (metres above the floor)";
  if (!(rebuild_tolerance >= 0.0)) return "mapping.rebuild_tolerance must be >= 0 (voxels)";
  return std::nullopt;
}

}  // namespace mcslam::mapping
