#include "mcslam/slam/objects.hpp"

#include <algorithm>

#include "object_geometry.hpp"

namespace mcslam::slam {
namespace {

/// Frames kept for carrying boxes forward: a detector slower than this many frames a detection
/// gets its boxes only grown.
constexpr std::size_t kRecentFrames = 12;
/// A moving region no evidence has confirmed for this many frames is dropped.
constexpr int kMoverLife = 10;
/// Moving regions carried to the next frames at most.
constexpr std::size_t kMaxMovers = 8;

/// Mean over the boxes of `truth` of the best IoU of a box of the same class in `estimate`;
/// boxes with no counterpart at all (objects that just appeared) are not counted. -1: none.
double mean_best_iou(const std::vector<perception::Detection>& truth,
                     const std::vector<perception::Detection>& estimate) {
  double sum = 0.0;
  int n = 0;
  for (const auto& t : truth) {
    double best = 0.0;
    for (const auto& e : estimate)
      if (e.class_name == t.class_name) best = std::max(best, perception::iou(t.box, e.box));
    if (best <= 0.0) continue;
    sum += best;
    ++n;
  }
  return n > 0 ? sum / n : -1.0;
}

/// The frame's detections, best score first, at most kMaxBoxes.
std::vector<perception::Detection> ranked(std::vector<perception::Detection> detections) {
  std::stable_sort(detections.begin(), detections.end(),
                   [](const auto& a, const auto& b) { return a.score > b.score; });
  if (detections.size() > kMaxBoxes) detections.resize(kMaxBoxes);
  return detections;
}

}  // namespace

const char* to_string(ObjectReport::Source source) {
  switch (source) {
    case ObjectReport::Source::kFresh:
      return "fresh";
    case ObjectReport::Source::kPropagated:
      return "propagated";
    case ObjectReport::Source::kGrown:
      return "grown";
    case ObjectReport::Source::kMover:
      return "moving_region";
  }
  return "unknown";
}

ObjectHandler::ObjectHandler(const PinholeCamera& camera, const DynamicsOptions& options)
    : camera_(camera), options_(options) {}

const ObjectFrame* ObjectHandler::recent(std::uint64_t id) const {
  for (const ObjectFrame& f : recent_)
    if (f.id == id) return &f;
  return nullptr;
}

std::vector<ObjectState> ObjectHandler::box_states() const {
  std::vector<ObjectState> state(boxes_.size());
  for (std::size_t b = 0; b < boxes_.size(); ++b)
    state[b] = tracks_.tracks()[static_cast<std::size_t>(boxes_[b].track)].state;
  return state;
}

void ObjectHandler::start_frame(const Frame& frame) {
  const auto& features = *frame.features;
  boxes_.clear();
  fresh_ = true;
  age_ = 0;
  decisions_.clear();
  constraints_.clear();
  constrained_points_.clear();
  constrained_lines_.clear();
  threshold_ = 0.0;
  propagation_iou_ = stale_iou_ = -1.0;
  mover_regions_ = mover_points_ = 0;
  feature_boxes_.points.assign(features.points.size(), 0);
  feature_boxes_.lines.assign(features.lines.size(), 0);
  point_excluded_.assign(features.points.size(), 0);
  line_excluded_.assign(features.lines.size(), 0);
  point_mover_.assign(features.points.size(), 0);
  line_mover_.assign(features.lines.size(), 0);
  recent_.push_front(ObjectFrame{frame.id, frame.features, std::nullopt});
  while (recent_.size() > kRecentFrames) recent_.pop_back();
}

void ObjectHandler::prepare(const Frame& frame, const std::optional<SE3>& predicted_T_c_w) {
  start_frame(frame);
  if (!options_.enabled || !frame.objects) {
    tracks_.clear();
    movers_.clear();
    return;
  }
  const auto& features = *frame.features;
  const std::vector<perception::Detection> detections = ranked(frame.objects->boxes);
  fresh_ = frame.objects->fresh;
  age_ = std::max(0, frame.objects->age);
  const std::uint64_t source = frame.id >= static_cast<std::uint64_t>(age_) ? frame.id - age_ : 0;
  const ObjectFrame* from = recent(source);
  std::vector<ObjectBox> boxes =
      carry_boxes(detections, BoxCarry{from, &features, predicted_T_c_w, age_, BoxSource::kFresh},
                  camera_, options_);
  measure_propagation(detections, source, from, frame.id, predicted_T_c_w);
  carry_movers(boxes, frame, predicted_T_c_w);
  boxes_ = std::move(boxes);
  associate_tracks();
  const std::vector<cv::Rect2f> plane_extent = frame_plane_extents(features, camera_);
  grow_flat_movers(boxes_, features, plane_extent, camera_, options_);
  feature_boxes_ = assign_features(features, plane_extent, boxes_, options_);
  update_exclusions();
}

void ObjectHandler::associate_tracks() {
  std::vector<perception::Detection> dets;
  for (const ObjectBox& b : boxes_) dets.push_back(b.detection);
  // New tracks of self-moving classes and moving regions start dynamic (the class prior).
  const auto tracks = tracks_.associate(dets, [this](const perception::Detection& d) {
    return options_.self_moving(d.class_name) || d.class_name == kMovingRegionClass;
  });
  for (std::size_t b = 0; b < boxes_.size(); ++b) boxes_[b].track = tracks[b];
}

void ObjectHandler::measure_propagation(const std::vector<perception::Detection>& detections,
                                        std::uint64_t source, const ObjectFrame* from,
                                        std::uint64_t frame_id,
                                        const std::optional<SE3>& predicted_T_c_w) {
  if (last_detection_frame_ && source > *last_detection_frame_ && from) {
    const ObjectFrame* previous = recent(*last_detection_frame_);
    const int gap = static_cast<int>(source - *last_detection_frame_);
    if (previous) {
      const std::optional<SE3> T_from_w = source == frame_id ? predicted_T_c_w : from->T_c_w;
      const BoxCarry carry{previous, from->features.get(), T_from_w, gap, BoxSource::kFresh};
      std::vector<perception::Detection> carried, stale;
      for (const ObjectBox& b : carry_boxes(last_detection_, carry, camera_, options_))
        carried.push_back(b.detection);
      for (auto d : last_detection_) {
        d.box = object_geometry::aged(d.box, gap);
        stale.push_back(d);
      }
      propagation_iou_ = mean_best_iou(detections, carried);
      stale_iou_ = mean_best_iou(detections, stale);
    }
  }
  if (!last_detection_frame_ || source != *last_detection_frame_) {
    last_detection_frame_ = source;
    last_detection_ = detections;
  }
}

void ObjectHandler::carry_movers(std::vector<ObjectBox>& boxes, const Frame& frame,
                                 const std::optional<SE3>& T_c_w) const {
  for (const MovingRegion& m : movers_) {
    if (boxes.size() >= kMaxBoxes) break;
    const int age = static_cast<int>(frame.id - m.frame);
    const BoxCarry carry{recent(m.frame), frame.features.get(), T_c_w, age, BoxSource::kMover};
    ObjectBox box = carry_boxes({m.detection}, carry, camera_, options_).front();
    box.source = BoxSource::kMover;
    box.unconfirmed = m.unconfirmed;
    box.age = age;
    box.flat = m.flat;
    box.last_depth = m.depth;
    boxes.push_back(box);
  }
}

void ObjectHandler::update_exclusions() {
  const std::vector<ObjectState> state = box_states();
  for (std::size_t i = 0; i < feature_boxes_.points.size(); ++i)
    point_excluded_[i] =
        point_mover_[i] || label_for(feature_boxes_.points[i], state) != FeatureLabel::kStatic ? 1
                                                                                               : 0;
  for (std::size_t i = 0; i < feature_boxes_.lines.size(); ++i)
    line_excluded_[i] =
        line_mover_[i] || label_for(feature_boxes_.lines[i], state) != FeatureLabel::kStatic ? 1
                                                                                             : 0;
}

void ObjectHandler::include_all() {
  std::fill(point_excluded_.begin(), point_excluded_.end(), 0);
  std::fill(line_excluded_.begin(), line_excluded_.end(), 0);
}

int ObjectHandler::static_points_with_depth(const Frame& frame) const {
  int n = 0;
  for (std::size_t i = 0; i < frame.features->points.size(); ++i)
    n += frame.features->points[i].has_depth() && !point_excluded(i) ? 1 : 0;
  return n;
}

void ObjectHandler::classify(const Frame& frame, const SE3& T_c_w) {
  const std::size_t n_boxes = boxes_.size();
  decisions_.assign(n_boxes, ObjectDecision{});
  constraints_.assign(n_boxes, ConstraintDecision{});
  constrained_points_.clear();
  constrained_lines_.clear();
  if (n_boxes == 0) return;
  // The reference: dynamics.frame_gap tracked frames back, or the oldest one kept.
  const ObjectFrame* reference =
      history_.empty()
          ? nullptr
          : &history_[std::min(history_.size(), static_cast<std::size_t>(options_.frame_gap)) - 1];
  std::vector<MotionMatch> matches;
  const std::optional<ConstraintFrame> planes =
      reference ? std::optional<ConstraintFrame>(
                      constraint_frame(frame.features->planes, T_c_w, *reference->T_c_w))
                : std::nullopt;
  if (reference) {
    BoxVerdicts verdicts = judge_boxes(*frame.features, T_c_w, *reference, history_.front(),
                                       feature_boxes_, n_boxes, camera_, options_);
    matches = std::move(verdicts.matches);
    decisions_ = std::move(verdicts.decisions);
    threshold_ = verdicts.threshold;
    update_tracks(matches);
    check_constraints(*planes, matches);
  }
  update_exclusions();
  // Moving regions: confirmed while Algorithm 1 keeps finding them moving, dropped when found
  // still (their track turned static) or unconfirmed for too long.
  movers_ = surviving_movers(boxes_, box_states(), decisions_, frame.id, kMoverLife);
  if (!reference) return;
  ConstraintMeasurements residuals = constraint_measurements(matches, box_states(), feature_boxes_,
                                                             constraints_, *planes, options_);
  constrained_points_ = std::move(residuals.points);
  constrained_lines_ = std::move(residuals.lines);
}

void ObjectHandler::update_tracks(const std::vector<MotionMatch>& matches) {
  const std::size_t n_boxes = boxes_.size();
  std::vector<bool> moving(n_boxes);
  for (std::size_t b = 0; b < n_boxes; ++b)
    moving[b] =
        decisions_[b].dynamic ||
        tracks_.tracks()[static_cast<std::size_t>(boxes_[b].track)].state != ObjectState::kStatic;
  withhold_shared_verdicts(decisions_, matches, boxes_, moving);
  for (std::size_t b = 0; b < n_boxes; ++b) {
    decisions_[b].box = static_cast<int>(b);
    const TrackEvidence e =
        track_evidence(decisions_[b], boxes_[b].detection.class_name, threshold_, options_);
    tracks_.update(boxes_[b].track, e.evidence, e.frames_to_clear);
  }
}

void ObjectHandler::check_constraints(const ConstraintFrame& planes,
                                      const std::vector<MotionMatch>& matches) {
  for (std::size_t b = 0; b < boxes_.size(); ++b) {
    const int t = boxes_[b].track;
    if (tracks_.tracks()[static_cast<std::size_t>(t)].state == ObjectState::kStatic) continue;
    if (!options_.constraints || !options_.constrainable(boxes_[b].detection.class_name)) {
      tracks_.set_constrained(t, false, -1);
      continue;
    }
    constraints_[b] = check_box_constraint(b, boxes_[b], matches, planes, camera_, options_);
    tracks_.set_constrained(t, constraints_[b].constrained, constraints_[b].plane);
  }
}

MoverResult ObjectHandler::find_movers(const Frame& frame, const SE3& T_c_w,
                                       const std::vector<MotionEvidence>& evidence) {
  MoverResult result;
  if (!options_.enabled || !options_.find_movers || !frame.objects) return result;
  const auto& features = *frame.features;
  const MotionSeeds seeds = motion_seeds(features, evidence, point_excluded_, camera_, options_);
  std::vector<MovingRegion> previous_candidates;
  for (const MovingRegion& c : candidates_)
    if (frame.id - c.frame <= 2) previous_candidates.push_back(c);
  candidates_.clear();
  if (seeds.count < options_.mover_min_seeds) return result;
  const std::vector<std::uint8_t> moving_plane = moving_planes(features, seeds, options_);
  const RegionNodes nodes = region_nodes(features, seeds, point_excluded_, moving_plane);
  for (const auto& members : connected_regions(features, nodes, seeds, options_)) {
    const auto region = mover_region(features, members, seeds, nodes.with_depth, options_);
    if (!region) continue;
    // Seen in two frames in a row at the same place, or it is only a candidate: depth noise at
    // an object's edge and a mismatch or two can make one frame's region, rarely the same one
    // twice.
    if (!seen_before(region->box, previous_candidates, frame, T_c_w)) {
      candidates_.push_back(MovingRegion{*region, frame.id, 0, false});
      continue;
    }
    const bool flat =
        take_region(features, members, region->box, seeds, moving_plane, result.moved_landmarks);
    ++mover_regions_;
    mover_points_ += static_cast<int>(members.size());
    result.any = true;
    // The region is carried to the next frames as a box, unless a known moving object's box
    // already covers it.
    bool covered = false;
    const auto state = box_states();
    for (std::size_t b = 0; b < boxes_.size(); ++b)
      covered = covered || (state[b] != ObjectState::kStatic &&
                            perception::iou(boxes_[b].detection.box, region->box) > 0.5);
    if (!covered && movers_.size() < kMaxMovers) {
      std::vector<float> depths;
      for (const auto i : members)
        if (features.points[i].has_depth()) depths.push_back(features.points[i].depth);
      const float depth = depths.empty() ? -1.0f : object_geometry::median_of(depths);
      movers_.push_back(MovingRegion{*region, frame.id, 0, flat, depth});
    }
  }
  if (result.any) update_exclusions();
  return result;
}

bool ObjectHandler::seen_before(const cv::Rect2f& region, const std::vector<MovingRegion>& previous,
                                const Frame& frame, const SE3& T_c_w) const {
  bool confirmed = false;
  for (const MovingRegion& c : previous) {
    const BoxCarry carry{recent(c.frame), frame.features.get(), T_c_w,
                         static_cast<int>(frame.id - c.frame), BoxSource::kMover};
    const cv::Rect2f r = carry_boxes({c.detection}, carry, camera_, options_).front().detection.box;
    const double overlap = (r & region).area();
    confirmed = confirmed || overlap > 0.5 * std::min(r.area(), region.area());
  }
  return confirmed;
}

bool ObjectHandler::take_region(const features::FrameFeatures& features,
                                const std::vector<std::size_t>& members, const cv::Rect2f& region,
                                const MotionSeeds& seeds,
                                const std::vector<std::uint8_t>& moving_plane,
                                std::vector<map::PointId>& moved) {
  float z0 = 1e9f, z1 = -1e9f;
  bool flat = false;
  for (std::size_t m : members) {
    flat = flat || object_geometry::on_moving_plane(features.points[m], moving_plane);
    point_mover_[m] = 1;
    if (seeds.seed[m] && seeds.landmark[m] != map::kNoId) moved.push_back(seeds.landmark[m]);
    z0 = std::min(z0, features.points[m].depth);
    z1 = std::max(z1, features.points[m].depth);
  }
  for (std::size_t i = 0; i < features.lines.size(); ++i) {
    const auto& l = features.lines[i];
    if (!l.has_depth || !object_geometry::contains(region, l.midpoint())) continue;
    const double z = 0.5 * (l.start_c.z() + l.end_c.z());
    if (z >= z0 - options_.mover_link_depth && z <= z1 + options_.mover_link_depth)
      line_mover_[i] = 1;
  }
  return flat;
}

void ObjectHandler::move_world(const SE3& W) {
  const SE3 W_inv = W.inverse();
  for (auto* frames : {&recent_, &history_})
    for (ObjectFrame& f : *frames)
      if (f.T_c_w) f.T_c_w = (*f.T_c_w) * W_inv;
}

void ObjectHandler::remember(const Frame& frame, const SE3& T_c_w) {
  if (!recent_.empty() && recent_.front().id == frame.id) recent_.front().T_c_w = T_c_w;
  history_.push_front(ObjectFrame{frame.id, frame.features, T_c_w});
  while (history_.size() > static_cast<std::size_t>(options_.frame_gap)) history_.pop_back();
}

void ObjectHandler::forget() {
  history_.clear();
  movers_.clear();
  candidates_.clear();
}

ObjectOutputs ObjectHandler::outputs(const Frame& frame) const {
  ObjectOutputs out;
  const auto& features = *frame.features;
  out.point_labels.assign(features.points.size(), FeatureLabel::kStatic);
  out.line_labels.assign(features.lines.size(), FeatureLabel::kStatic);
  out.fresh = fresh_;
  out.age = age_;
  out.threshold = threshold_;
  out.propagation_iou = propagation_iou_;
  out.stale_iou = stale_iou_;
  out.mover_regions = mover_regions_;
  out.mover_points = mover_points_;
  const std::vector<ObjectState> state = box_states();
  for (std::size_t b = 0; b < boxes_.size(); ++b) {
    const auto& track = tracks_.tracks()[static_cast<std::size_t>(boxes_[b].track)];
    ObjectReport r;
    r.detection = boxes_[b].detection;
    r.track_id = track.id;
    r.state = track.state;
    if (b < decisions_.size()) r.decision = decisions_[b];
    if (b < constraints_.size()) r.constraint = constraints_[b];
    r.source = boxes_[b].source;
    r.propagated_matches = boxes_[b].propagated_matches;
    r.depth_near = boxes_[b].depth_near;
    r.depth_far = boxes_[b].depth_far;
    r.background_points = boxes_[b].background_points;
    out.objects.push_back(r);
  }
  for (std::size_t i = 0; i < feature_boxes_.points.size(); ++i)
    out.point_labels[i] =
        point_mover_[i] ? FeatureLabel::kDynamic : label_for(feature_boxes_.points[i], state);
  for (std::size_t i = 0; i < feature_boxes_.lines.size(); ++i)
    out.line_labels[i] =
        line_mover_[i] ? FeatureLabel::kDynamic : label_for(feature_boxes_.lines[i], state);
  out.constrained_point_residuals = static_cast<int>(constrained_points_.size());
  out.constrained_line_residuals = static_cast<int>(constrained_lines_.size());
  return out;
}

}  // namespace mcslam::slam
