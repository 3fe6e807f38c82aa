// Object stages on the frame's boxes: carrying boxes detected on an earlier frame to the frame
// being tracked, and assigning the frame's features to its boxes.

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/video/tracking.hpp>

#include "mcslam/slam/object_stages.hpp"
#include "object_geometry.hpp"

namespace mcslam::slam {
namespace {

using object_geometry::aged;
using object_geometry::contains;
using object_geometry::grown;

/// Features of a box matched to carry it forward (a median needs no more).
constexpr std::size_t kPropagationSample = 40;

/// Where a feature of the detector's frame would be in the frame being tracked if it were
/// static: moved by T_to_from when both poses are known, else where it was.
struct CarryPrediction {
  const PinholeCamera& camera;
  const std::optional<SE3>& T_to_from;

  std::optional<Eigen::Vector2d> operator()(const features::PointFeature& f) const {
    const Eigen::Vector2d uv = f.keypoint.uv.cast<double>();
    if (!T_to_from) return uv;
    return object_geometry::static_prediction(camera, *T_to_from, uv,
                                              f.has_depth() ? f.depth : 0.0);
  }
};

/// A box's object in the detector's frame: a sample of its features (inside the box, and not
/// behind the object's depth band: the background moves with the camera, not with the object)
/// and that band.
struct ObjectSample {
  std::vector<std::size_t> points;
  std::optional<std::pair<float, float>> band;
};

ObjectSample sample_object(const features::FrameFeatures& old, const cv::Rect2f& r,
                           double depth_gap) {
  ObjectSample out;
  std::vector<std::size_t> inside;
  std::vector<float> depths;
  for (std::size_t i = 0; i < old.points.size(); ++i) {
    if (!contains(r, old.points[i].keypoint.uv)) continue;
    inside.push_back(i);
    if (old.points[i].has_depth()) depths.push_back(old.points[i].depth);
  }
  out.band = object_geometry::object_band(depths, depth_gap);
  std::vector<std::size_t> object;
  for (std::size_t i : inside)
    if (!out.band || !old.points[i].has_depth() || old.points[i].depth <= out.band->second)
      object.push_back(i);
  const std::size_t stride = std::max<std::size_t>(1, object.size() / kPropagationSample);
  for (std::size_t k = 0; k < object.size(); k += stride) out.points.push_back(object[k]);
  return out;
}

/// The image motion of each box's sampled features (indices into from.points) from `from`'s
/// image to `to`'s, by pyramidal Lucas-Kanade started at `predict` (where the camera's motion
/// alone puts them); a feature counts when tracking it back returns within `max_error` pixels.
/// One list of shifts per box; empty lists without images.
std::vector<std::vector<Eigen::Vector2d>> flow_shifts(const features::FrameFeatures& from,
                                                      const features::FrameFeatures& to,
                                                      const std::vector<ObjectSample>& samples,
                                                      const CarryPrediction& predict,
                                                      double max_error) {
  std::vector<std::vector<Eigen::Vector2d>> out(samples.size());
  if (from.image.empty() || to.image.empty() || from.image.size() != to.image.size()) return out;
  std::vector<cv::Point2f> start, moved;
  std::vector<std::size_t> box_of;
  for (std::size_t b = 0; b < samples.size(); ++b)
    for (std::size_t i : samples[b].points) {
      const features::PointFeature& f = from.points[i];
      const auto at = predict(f);
      if (!at) continue;
      start.emplace_back(f.keypoint.uv.x(), f.keypoint.uv.y());
      moved.emplace_back(static_cast<float>(at->x()), static_cast<float>(at->y()));
      box_of.push_back(b);
    }
  if (start.empty()) return out;
  // A 15 px window over 4 levels (3 halvings) follows ~60 px beyond the start: a person
  // crossing the view at 1.5 m/s, 1 m away, for 2-3 frames at 30 Hz. The pyramids are built
  // once and serve both directions.
  const cv::TermCriteria stop(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 0.03);
  const cv::Size window(15, 15);
  constexpr int kLevels = 3;
  std::vector<cv::Mat> from_pyramid, to_pyramid;
  cv::buildOpticalFlowPyramid(from.image, from_pyramid, window, kLevels);
  cv::buildOpticalFlowPyramid(to.image, to_pyramid, window, kLevels);
  std::vector<std::uint8_t> found, found_back;
  std::vector<float> error;
  cv::calcOpticalFlowPyrLK(from_pyramid, to_pyramid, start, moved, found, error, window, kLevels,
                           stop, cv::OPTFLOW_USE_INITIAL_FLOW);
  std::vector<cv::Point2f> back = start;
  cv::calcOpticalFlowPyrLK(to_pyramid, from_pyramid, moved, back, found_back, error, window,
                           kLevels, stop, cv::OPTFLOW_USE_INITIAL_FLOW);
  for (std::size_t k = 0; k < start.size(); ++k) {
    if (!found[k] || !found_back[k]) continue;
    if (cv::norm(back[k] - start[k]) > max_error) continue;
    out[box_of[k]].emplace_back(moved[k].x - start[k].x, moved[k].y - start[k].y);
  }
  return out;
}

/// Image shifts of a box's features, one list per axis.
struct Shifts {
  std::vector<double> dx, dy;
};

/// The shifts of the sampled features matched by descriptor near their prediction (within
/// match_radius + propagation_radius pixels a frame of `age`).
Shifts descriptor_shifts(const ObjectSample& sample, const features::FrameFeatures& old,
                         const features::FrameFeatures& to, const CarryPrediction& predict, int age,
                         const DynamicsOptions& options) {
  Shifts out;
  std::vector<int> candidates;
  for (std::size_t i : sample.points) {
    const auto& f = old.points[i];
    const auto at = predict(f);
    if (!at) continue;
    // The object's own motion does not scale with the keypoint's level: one radius.
    const int level = f.keypoint.level;
    const double radius = options.match_radius + options.propagation_radius * age;
    to.grid.query(static_cast<float>(at->x()), static_cast<float>(at->y()),
                  static_cast<float>(radius), std::max(0, level - 1), level + 1, candidates);
    const int best_idx = object_geometry::unambiguous_match(f.descriptor, candidates, to.points,
                                                            options.descriptor_distance);
    if (best_idx < 0) continue;
    const Eigen::Vector2f shift =
        to.points[static_cast<std::size_t>(best_idx)].keypoint.uv - f.keypoint.uv;
    out.dx.push_back(shift.x());
    out.dy.push_back(shift.y());
  }
  return out;
}

/// Moves a box by its features' median shift; with too few (a blurred or textureless object) it
/// moves with the camera at its band's depth and is grown as an unpropagated box would be. Then
/// the margin for what its motion misses (none for moving regions, re-fitted every frame).
void place_box(ObjectBox& b, const Shifts& shifts, const ObjectSample& sample,
               const std::optional<SE3>& T_to_from, int age, const PinholeCamera& camera,
               const DynamicsOptions& options) {
  const cv::Rect2f& r = b.detection.box;
  b.propagated_matches = static_cast<int>(shifts.dx.size());
  Eigen::Vector2d shift = Eigen::Vector2d::Zero();
  if (static_cast<int>(shifts.dx.size()) >= options.min_propagation_matches) {
    shift = {object_geometry::median_of(shifts.dx), object_geometry::median_of(shifts.dy)};
    if (b.source == BoxSource::kFresh) b.source = BoxSource::kPropagated;
  } else {
    const auto& band = sample.band;
    if (T_to_from && band) {
      const Eigen::Vector2d c(r.x + r.width / 2.0, r.y + r.height / 2.0);
      const double z = 0.5 * (band->first + band->second);
      const Eigen::Vector3d p = (*T_to_from) * camera.unproject(c, z);
      if (p.z() > 1e-6) shift = camera.project(p) - c;
    }
    b.detection.box = aged(r, age);
    if (b.source == BoxSource::kFresh) b.source = BoxSource::kGrown;
  }
  const float margin =
      b.source == BoxSource::kMover ? 0.0f : static_cast<float>(options.propagation_margin * age);
  cv::Rect2f moved = b.detection.box;
  moved.x += static_cast<float>(shift.x());
  moved.y += static_cast<float>(shift.y());
  b.detection.box = grown(moved, margin, margin);
}

}  // namespace

std::vector<ObjectBox> carry_boxes(const std::vector<perception::Detection>& detections,
                                   const BoxCarry& carry, const PinholeCamera& camera,
                                   const DynamicsOptions& options) {
  std::vector<ObjectBox> out;
  for (const auto& d : detections) {
    ObjectBox box;
    box.detection = d;
    box.source = carry.source;
    out.push_back(box);
  }
  if (carry.age <= 0) return out;
  if (!options.propagate_boxes || carry.from == nullptr) {
    for (ObjectBox& b : out) {
      b.detection.box = aged(b.detection.box, carry.age);
      if (b.source == BoxSource::kFresh) b.source = BoxSource::kGrown;
    }
    return out;
  }
  const auto& old = *carry.from->features;
  const auto& to = *carry.to;
  std::optional<SE3> T_to_from;
  if (carry.from->T_c_w && carry.T_to_w) T_to_from = (*carry.T_to_w) * carry.from->T_c_w->inverse();
  const CarryPrediction predict{camera, T_to_from};
  // Each box's sample of its object's features, followed by optical flow all at once.
  std::vector<ObjectSample> samples;
  for (const ObjectBox& b : out)
    samples.push_back(sample_object(old, b.detection.box, options.object_depth_gap));
  const std::vector<std::vector<Eigen::Vector2d>> flow =
      options.propagate_by_flow ? flow_shifts(old, to, samples, predict, options.flow_max_error)
                                : std::vector<std::vector<Eigen::Vector2d>>(out.size());
  for (std::size_t bi = 0; bi < out.size(); ++bi) {
    Shifts shifts;
    for (const Eigen::Vector2d& d : flow[bi]) {
      shifts.dx.push_back(d.x());
      shifts.dy.push_back(d.y());
    }
    // Too few followed by flow: matched by descriptor near the prediction instead.
    if (static_cast<int>(shifts.dx.size()) < options.min_propagation_matches)
      shifts = descriptor_shifts(samples[bi], old, to, predict, carry.age, options);
    place_box(out[bi], shifts, samples[bi], T_to_from, carry.age, camera, options);
  }
  return out;
}

std::vector<cv::Rect2f> frame_plane_extents(const features::FrameFeatures& features,
                                            const PinholeCamera& camera) {
  std::vector<cv::Rect2f> plane_extent;
  for (const auto& plane : features.planes) {
    float x0 = 1e9f, y0 = 1e9f, x1 = -1e9f, y1 = -1e9f;
    for (const auto& h : plane.hull) {
      if (h.z() <= 1e-3) continue;
      const Eigen::Vector2d uv = camera.project(h);
      x0 = std::min(x0, static_cast<float>(uv.x()));
      y0 = std::min(y0, static_cast<float>(uv.y()));
      x1 = std::max(x1, static_cast<float>(uv.x()));
      y1 = std::max(y1, static_cast<float>(uv.y()));
    }
    const cv::Rect2f r = x1 > x0 && y1 > y0 ? cv::Rect2f(x0, y0, x1 - x0, y1 - y0) : cv::Rect2f();
    plane_extent.push_back(r & cv::Rect2f(0.f, 0.f, static_cast<float>(camera.width),
                                          static_cast<float>(camera.height)));
  }
  return plane_extent;
}

namespace {

/// Limits a grown region's box to the image of an object mover_max_width x mover_max_height at
/// the depth the region was last seen at: along an axis where it would be larger, it does not
/// grow.
void keep_object_size(cv::Rect2f& region, const ObjectBox& box, const PinholeCamera& camera,
                      const DynamicsOptions& options, const cv::Rect2f& image) {
  const cv::Rect2f was = box.detection.box & image;
  const double z = box.last_depth;
  if (region.width > camera.fx * options.mover_max_width / z) {
    region.x = was.x;
    region.width = was.width;
  }
  if (region.height > camera.fy * options.mover_max_height / z) {
    region.y = was.y;
    region.height = was.height;
  }
}

}  // namespace

void grow_flat_movers(std::vector<ObjectBox>& boxes, const features::FrameFeatures& features,
                      const std::vector<cv::Rect2f>& plane_extent, const PinholeCamera& camera,
                      const DynamicsOptions& options) {
  // A moving region found on a moving plane holds part of a rigid surface, which moves whole: a
  // frame plane with most of its points inside the region's box is the region's (the flat face
  // of a box carried, a door), and the box grows towards the plane's extent (the object coming
  // further into view), by at most propagation_radius pixels a frame on each side: how far a
  // person's image moves in a frame. A plane reaching farther (the floor, a wall) is only
  // partly taken, and only while the box still holds most of it.
  const cv::Rect2f image(0.0f, 0.0f, static_cast<float>(camera.width),
                         static_cast<float>(camera.height));
  const std::size_t n_planes = features.planes.size();
  const auto plane_of = [&](const features::PointFeature& f) -> std::optional<std::size_t> {
    if (f.plane < 0 || static_cast<std::size_t>(f.plane) >= n_planes) return std::nullopt;
    return static_cast<std::size_t>(f.plane);
  };
  std::vector<int> total(n_planes, 0);
  for (const auto& f : features.points)
    if (const auto k = plane_of(f)) ++total[*k];
  for (ObjectBox& box : boxes) {
    if (box.source != BoxSource::kMover || !box.flat) continue;
    std::vector<int> inside(n_planes, 0);
    for (const auto& f : features.points)
      if (const auto k = plane_of(f)) inside[*k] += contains(box.detection.box, f.keypoint.uv);
    const auto reach = static_cast<float>(options.propagation_radius * std::max(1, box.age));
    const cv::Rect2f bound = grown(box.detection.box, reach, reach) & image;
    cv::Rect2f region = box.detection.box & image;
    for (std::size_t k = 0; k < n_planes; ++k) {
      if (2 * inside[k] <= total[k] || plane_extent[k].area() <= 0.0f) continue;
      cv::Rect2f extent = plane_extent[k];
      extent.width += 1.0f;  // a box holds the pixels on its far edges too, as a region's does
      extent.height += 1.0f;
      region |= extent & bound;
    }
    if (box.last_depth > 0.0f) keep_object_size(region, box, camera, options, image);
    box.detection.box = region;
  }
}

namespace {

/// The geometry of a frame's boxes that decides which of them a feature belongs to.
class BoxGeometry {
 public:
  BoxGeometry(const std::vector<ObjectBox>& boxes, const std::vector<cv::Rect2f>& plane_extent,
              const DynamicsOptions& options)
      : boxes_(boxes), plane_extent_(plane_extent), options_(options) {}

  /// Whether frame plane `plane` is structural for box `b`: most of its extent lies outside it
  /// (the floor or a wall seen through the box).
  bool structural(std::size_t b, int plane) const {
    if (plane < 0 || static_cast<std::size_t>(plane) >= plane_extent_.size()) return false;
    const cv::Rect2f& e = plane_extent_[static_cast<std::size_t>(plane)];
    const double area = e.area();
    if (area <= 0.0) return false;
    const double inside = (e & boxes_[b].detection.box).area();
    return 1.0 - inside / area >= options_.structural_outside;
  }
  /// Whether a feature at `depth` is background behind box b's object.
  bool behind(std::size_t b, double depth) const {
    return options_.separate_background && depth > 0.0 && boxes_[b].depth_far > 0.0f &&
           depth > boxes_[b].depth_far;
  }
  /// Of the boxes of `mask`, the one whose object depth is closest to `depth` (a person walking
  /// in front of a cupboard); `mask` as it is without depth or with a single box.
  std::uint64_t nearest_box(std::uint64_t mask, double depth) const {
    if (depth <= 0.0 || (mask & (mask - 1)) == 0) return mask;
    std::uint64_t best = mask;
    double best_gap = std::numeric_limits<double>::infinity();
    for (std::size_t b = 0; b < boxes_.size(); ++b) {
      if (!((mask >> b) & 1U) || boxes_[b].depth < 0.0f) continue;
      const double gap = std::abs(boxes_[b].depth - depth);
      if (gap < best_gap) {
        best_gap = gap;
        best = std::uint64_t{1} << b;
      }
    }
    return best;
  }

 private:
  const std::vector<ObjectBox>& boxes_;
  const std::vector<cv::Rect2f>& plane_extent_;
  const DynamicsOptions& options_;
};

/// The boxes containing each point, less those for which the point's plane is structural.
std::vector<std::uint64_t> points_in_boxes(const features::FrameFeatures& features,
                                           const std::vector<ObjectBox>& boxes,
                                           const BoxGeometry& geometry) {
  std::vector<std::uint64_t> mask(features.points.size(), 0);
  for (std::size_t i = 0; i < features.points.size(); ++i) {
    const auto& f = features.points[i];
    for (std::size_t b = 0; b < boxes.size(); ++b) {
      if (!contains(boxes[b].detection.box, f.keypoint.uv)) continue;
      if (geometry.structural(b, f.plane)) continue;
      mask[i] |= std::uint64_t{1} << b;
    }
  }
  return mask;
}

/// Each box's object depth band and median depth: from the features in it alone when it has
/// some (a cupboard's depth from the part of it a person in front does not hide), else from all
/// of its features; a moving region's at the depth it was last seen at.
void set_box_depths(std::vector<ObjectBox>& boxes, const features::FrameFeatures& features,
                    const std::vector<std::uint64_t>& mask, double depth_gap) {
  const std::size_t n_boxes = boxes.size();
  std::vector<std::vector<float>> box_depths(n_boxes), exclusive_depths(n_boxes);
  for (std::size_t i = 0; i < features.points.size(); ++i) {
    if (!features.points[i].has_depth()) continue;
    for (std::size_t b = 0; b < n_boxes; ++b) {
      if (!((mask[i] >> b) & 1U)) continue;
      box_depths[b].push_back(features.points[i].depth);
      if (mask[i] == std::uint64_t{1} << b) exclusive_depths[b].push_back(features.points[i].depth);
    }
  }
  for (std::size_t b = 0; b < n_boxes; ++b) {
    auto& d = exclusive_depths[b].size() >= 5 ? exclusive_depths[b] : box_depths[b];
    const auto band = object_geometry::object_band(d, depth_gap, boxes[b].last_depth);
    if (!band) continue;
    std::vector<float> own;
    for (float z : d)
      if (z >= band->first && z <= band->second) own.push_back(z);
    boxes[b].depth = object_geometry::median_of(own);
    boxes[b].depth_near = band->first;
    boxes[b].depth_far = band->second;
  }
}

/// The boxes each segment belongs to: those containing its midpoint, unless it lies on a plane
/// structural for the box or both its ends are behind the object; of several, the one at its
/// depth.
std::vector<std::uint64_t> lines_in_boxes(const features::FrameFeatures& features,
                                          const std::vector<ObjectBox>& boxes,
                                          const BoxGeometry& geometry, const DynamicsOptions& opt) {
  std::vector<std::uint64_t> mask(features.lines.size(), 0);
  for (std::size_t i = 0; i < features.lines.size(); ++i) {
    const auto& l = features.lines[i];
    for (std::size_t b = 0; b < boxes.size(); ++b) {
      if (!contains(boxes[b].detection.box, l.midpoint())) continue;
      bool on_structure = false;
      if (l.has_depth)
        for (std::size_t k = 0; k < features.planes.size() && !on_structure; ++k)
          on_structure = geometry.structural(b, static_cast<int>(k)) &&
                         std::abs(features.planes[k].distance(l.start_c)) < opt.plane_distance &&
                         std::abs(features.planes[k].distance(l.end_c)) < opt.plane_distance;
      if (!on_structure) mask[i] |= std::uint64_t{1} << b;
    }
    if (l.has_depth && opt.separate_background) {
      const double near_end = std::min(l.start_c.z(), l.end_c.z());
      for (std::size_t b = 0; b < boxes.size(); ++b)
        if (((mask[i] >> b) & 1U) && geometry.behind(b, near_end))
          mask[i] &= ~(std::uint64_t{1} << b);
    }
    mask[i] =
        geometry.nearest_box(mask[i], l.has_depth ? 0.5 * (l.start_c.z() + l.end_c.z()) : 0.0);
  }
  return mask;
}

}  // namespace

FeatureBoxes assign_features(const features::FrameFeatures& features,
                             const std::vector<cv::Rect2f>& plane_extent,
                             std::vector<ObjectBox>& boxes, const DynamicsOptions& options) {
  const BoxGeometry geometry(boxes, plane_extent, options);
  FeatureBoxes out;
  out.points = points_in_boxes(features, boxes, geometry);
  set_box_depths(boxes, features, out.points, options.object_depth_gap);
  // A point behind a box's object is that box's background; of the boxes left, the one at the
  // point's depth.
  for (std::size_t i = 0; i < features.points.size(); ++i) {
    const double depth = features.points[i].has_depth() ? features.points[i].depth : 0.0;
    std::uint64_t mask = out.points[i];
    for (std::size_t b = 0; b < boxes.size(); ++b)
      if (((mask >> b) & 1U) && geometry.behind(b, depth)) {
        mask &= ~(std::uint64_t{1} << b);
        ++boxes[b].background_points;
      }
    out.points[i] = geometry.nearest_box(mask, depth);
  }
  out.lines = lines_in_boxes(features, boxes, geometry, options);
  return out;
}

}  // namespace mcslam::slam
