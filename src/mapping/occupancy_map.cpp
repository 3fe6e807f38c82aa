#include "mcslam/mapping/occupancy_map.hpp"

#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <map>
#include <opencv2/imgproc.hpp>
#include <string>
#include <tuple>
#include <utility>

#include "mapping/collector.hpp"
#include "mapping/key_marks.hpp"
#include "mapping/octree_walk.hpp"
#include "mapping/ordered_pipeline.hpp"
#include "mcslam/core/error.hpp"

namespace mcslam::mapping {

namespace {

using detail::ColourSum;
using detail::kCrossed;
using detail::kHit;
using detail::kMoverHit;
using detail::kSpreadHit;
using ColourMap = std::unordered_map<octomap::OcTreeKey, ColourSum, octomap::OcTreeKey::KeyHash>;

void check_image(const cv::Mat& image, int type, const KeyframeDepth& kf, const char* what) {
  if (image.empty()) return;
  if (image.type() != type || image.cols != kf.camera.width || image.rows != kf.camera.height)
    throw InputError("keyframe " + std::to_string(kf.id) + ": the " + what + " image must be " +
                     std::to_string(kf.camera.width) + "x" + std::to_string(kf.camera.height) +
                     " of type " + cv::typeToString(type) + ", got " + std::to_string(image.cols) +
                     "x" + std::to_string(image.rows) + " " + cv::typeToString(image.type()));
}

std::uint16_t to_millimetres(float z) {
  if (!(z > 0.0f) || !std::isfinite(z)) return 0;
  return static_cast<std::uint16_t>(std::min(65535.0f, std::max(1.0f, std::round(z * 1000.0f))));
}

/// The median of the valid depths of the block of `step` x `step` pixels at (x0, y0) (0 when
/// none): one of them, so that a block across a depth edge takes one side's depth and never a
/// depth between the two.
float block_median(const cv::Mat& depth, int x0, int y0, int step, std::vector<float>& values) {
  values.clear();
  for (int r = y0; r < y0 + step; ++r) {
    const float* row = depth.ptr<float>(r) + x0;
    for (int c = 0; c < step; ++c)
      if (row[c] > 0.0f && std::isfinite(row[c])) values.push_back(row[c]);
  }
  if (values.empty()) return 0.0f;
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

/// Whether any pixel of the block of `step` x `step` pixels at (x0, y0) of a CV_8UC1 mask is set
/// (false for an empty mask).
bool any_in_block(const cv::Mat& mask, int x0, int y0, int step) {
  if (mask.empty()) return false;
  for (int r = y0; r < y0 + step; ++r) {
    const std::uint8_t* row = mask.ptr<std::uint8_t>(r) + x0;
    for (int c = 0; c < step; ++c)
      if (row[c] != 0) return true;
  }
  return false;
}

}  // namespace

std::size_t KeyframeSamples::bytes() const {
  const auto size = [](const cv::Mat& m) { return m.empty() ? 0 : m.total() * m.elemSize(); };
  return size(depth_mm) + size(kind) + size(colour);
}

KeyframeSamples sample_keyframe(const KeyframeDepth& kf, const OccupancyOptions& options) {
  if (auto problem = kf.camera.check())
    throw InputError("keyframe " + std::to_string(kf.id) + ": " + *problem);
  if (kf.depth.empty()) throw InputError("keyframe " + std::to_string(kf.id) + ": no depth image");
  check_image(kf.depth, CV_32FC1, kf, "depth");
  check_image(kf.dynamic_mask, CV_8UC1, kf, "dynamic mask");
  check_image(kf.mover_mask, CV_8UC1, kf, "mover mask");
  check_image(kf.colour, CV_8UC3, kf, "colour");

  KeyframeSamples s;
  s.id = kf.id;
  s.T_w_c = kf.T_w_c;
  s.camera = kf.camera;
  s.step = options.effective_pixel_step(kf.camera);
  const int cols = kf.camera.width / s.step;
  const int rows = kf.camera.height / s.step;
  const int offset = (s.step - 1) / 2;
  cv::Mat mask;
  const cv::Mat mover_mask = options.use_masks ? kf.mover_mask : cv::Mat();
  if (!options.use_masks) {
    // every pixel a static surface (OccupancyOptions::use_masks)
  } else if (!kf.dynamic_mask.empty() && options.mask_dilation_px > 0) {
    const int k = 2 * options.mask_dilation_px + 1;
    cv::dilate(kf.dynamic_mask, mask, cv::getStructuringElement(cv::MORPH_ELLIPSE, {k, k}));
  } else {
    mask = kf.dynamic_mask;
  }
  const bool colour = options.store_colour && !kf.colour.empty();
  s.depth_mm.create(rows, cols, CV_16UC1);
  s.kind = cv::Mat::zeros(rows, cols, CV_8UC1);
  if (colour) s.colour.create(rows, cols, CV_8UC3);
  std::vector<float> block;
  for (int j = 0; j < rows; ++j) {
    const int y = j * s.step;
    auto* depth_mm = s.depth_mm.ptr<std::uint16_t>(j);
    auto* kind = s.kind.ptr<std::uint8_t>(j);
    for (int i = 0; i < cols; ++i) {
      const int x = i * s.step;
      depth_mm[i] = to_millimetres(block_median(kf.depth, x, y, s.step, block));
      if (any_in_block(mask, x, y, s.step))
        kind[i] = KeyframeSamples::kDynamic;
      else if (any_in_block(mover_mask, x, y, s.step))
        kind[i] = KeyframeSamples::kMover;
      if (colour) s.colour.at<cv::Vec3b>(j, i) = kf.colour.at<cv::Vec3b>(y + offset, x + offset);
    }
  }
  return s;
}

struct OccupancyMap::Impl {
  OccupancyOptions options;
  octomap::OcTree tree;
  std::vector<KeyframeSamples> keyframes;
  std::unordered_map<KeyframeId, std::size_t> index;
  ColourMap colours;
  std::vector<double> insert_ms;
  std::size_t rebuilds = 0;
  double last_rebuild_ms = 0.0;
  float hit_log = 0.0f;
  float miss_log = 0.0f;
  /// What one integration's samples did to each voxel (the scratch space is kept).
  detail::Collector collector;
  octomap::KeySet volatile_keys;  ///< voxels a mover marked last (across keyframes)
  /// OccupancyOptions::integration "at_end": keyframes are stored, integrated later.
  bool deferred = false;
  bool pending = false;  ///< stored keyframes not in the octree yet (deferred)

  explicit Impl(const OccupancyOptions& o)
      : options(o), tree(o.resolution), deferred(o.integration == "at_end") {
    configure();
  }
  /// A deep copy: the octree's nodes are copied, the keyframes' sample images shared (they
  /// are never written once stored).
  Impl(const Impl& other) = default;
  Impl& operator=(const Impl&) = delete;

  void configure() {
    tree.setProbHit(options.prob_hit);
    tree.setProbMiss(options.prob_miss);
    tree.setOccupancyThres(options.prob_occupied);
    tree.setClampingThresMin(options.clamp_min);
    tree.setClampingThresMax(options.clamp_max);
    hit_log = octomap::logodds(options.prob_hit);
    miss_log = octomap::logodds(options.prob_miss);
  }

  /// The samples of stored keyframe `kf` inside `region` (its box, its depth band) that are
  /// static become movers (the kind image is copied first: clones share it), and the voxels they
  /// hit become volatile: freed at once by the next ray that crosses them.
  void relabel_as_mover(KeyframeSamples& kf, const ObjectRegion& region) {
    kf.kind = kf.kind.clone();
    const Eigen::Matrix3d R = kf.T_w_c.rotation();
    const Eigen::Vector3d o = kf.T_w_c.translation();
    octomap::KeySet keys;
    for (int j = 0; j < kf.kind.rows; ++j) {
      for (int i = 0; i < kf.kind.cols; ++i) {
        std::uint8_t& kind = kf.kind.at<std::uint8_t>(j, i);
        const std::uint16_t mm = kf.depth_mm.at<std::uint16_t>(j, i);
        const Eigen::Vector2d uv = kf.pixel(i, j);
        if (kind != KeyframeSamples::kStatic || mm == 0 ||
            !region.box.contains(
                cv::Point2f(static_cast<float>(uv.x()), static_cast<float>(uv.y()))))
          continue;
        const double z = 1e-3 * mm;
        if (region.depth_far > 0.0f && (z < region.depth_near || z > region.depth_far)) continue;
        kind = KeyframeSamples::kMover;
        if (z > options.max_range) continue;
        const Eigen::Vector3d dir_z = R * kf.ray(i, j);
        collector.add_hit(tree, o, dir_z, z, options.depth_sigma(z),
                          [&keys](const octomap::OcTreeKey& k, bool) { keys.insert(k); });
      }
    }
    volatile_keys.insert(keys.begin(), keys.end());
  }

  /// Objects seen standing still, by id: where each stored keyframe saw it.
  std::unordered_map<int, std::vector<std::pair<KeyframeId, ObjectRegion>>> still_objects;

  /// Records the keyframe's still objects; for each of its moving objects that was seen still
  /// before, relabels those samples as a mover's (its first place is then forgotten as soon as
  /// a keyframe sees through it).
  void note_objects(const KeyframeDepth& kf) {
    for (const ObjectRegion& r : kf.still_objects)
      if (r.id >= 0) still_objects[r.id].emplace_back(kf.id, r);
    for (const int id : kf.moving_objects) {
      const auto found = still_objects.find(id);
      if (found == still_objects.end()) continue;
      for (const auto& [kf_id, region] : found->second) {
        const auto stored = index.find(kf_id);
        if (stored != index.end()) relabel_as_mover(keyframes[stored->second], region);
      }
      still_objects.erase(found);
    }
  }

  /// Sets a voxel to `bound` moved by `update` when that is further (a mover's voxel: occupied
  /// at once, or free at once).
  void set_at_least_past(const octomap::OcTreeKey& key, float update) {
    const octomap::OcTreeNode* node = tree.search(key);
    const float now = node != nullptr ? node->getLogOdds() : 0.0f;
    const float bound = tree.getOccupancyThresLog();
    tree.setNodeValue(
        key, update > 0.0f ? std::max(now, bound) + update : std::min(now, bound) + update, true);
  }

  /// The tree's nodes when settle() last ran.
  std::size_t settled_size = 0;

  void integrate(const KeyframeSamples& s);
  void apply(const detail::Collector& collected);
  void settle();
  void reintegrate_all();
  void reintegrate_with_helpers(std::size_t helpers);
  bool integrate_pending_keyframes() {
    if (!pending) return false;
    reintegrate_all();
    return true;
  }
};

void OccupancyMap::Impl::integrate(const KeyframeSamples& s) {
  collector.collect(tree, options, s);
  apply(collector);
}

void OccupancyMap::Impl::apply(const detail::Collector& collected) {
  const detail::KeyMarks& marks = collected.marks();
  const std::vector<ColourSum>& hit_colours = collected.colours();
  for (std::size_t e = 0; e < hit_colours.size(); ++e) {
    const ColourSum& c = hit_colours[e];
    if (c.n == 0) continue;
    ColourSum& sum = colours[marks.entries()[e].key];
    sum.b += c.b;
    sum.g += c.g;
    sum.r += c.r;
    sum.n += c.n;
  }
  // One update per voxel. A voxel that one measurement of the keyframe hit is not freed by
  // another one passing by; a static hit makes it static. A voxel that only the spread of hits
  // reached is freed when more of the keyframe's rays crossed it (spread_yield_ratio).
  const double yield = options.spread_yield_ratio;
  detail::LeafFinder leaves(tree);
  // OcTree::updateNode's own first step, from the path of the voxel before: no change where the
  // voxel is clamped already (most of the free space a keyframe sees again). A voxel that is a
  // node of its own is updated in place, as updateNode's lazy update does at the end of its own
  // two walks from the root; a new or pruned one goes through updateNode, which makes its node.
  const auto update = [&](const octomap::OcTreeKey& key, float log_odds) {
    const octomap::OcTreeNode* leaf = leaves.find(key);
    if (leaf == nullptr) {
      tree.updateNode(key, log_odds, true);
      return;
    }
    if (log_odds >= 0.0f ? leaf->getLogOdds() >= tree.getClampingThresMaxLog()
                         : leaf->getLogOdds() <= tree.getClampingThresMinLog())
      return;
    if (leaves.depth() == static_cast<int>(tree.getTreeDepth()))
      tree.updateNodeLogOdds(const_cast<octomap::OcTreeNode*>(leaf), log_odds);  // the tree's own
    else
      tree.updateNode(key, log_odds, true);
  };
  for (const detail::KeyMarks::Entry& e : marks.entries()) {
    const octomap::OcTreeKey& key = e.key;
    const bool spread_holds = (e.roles & kSpreadHit) != 0 && !(static_cast<double>(e.spread) <
                                                               yield * static_cast<double>(e.rays));
    if ((e.roles & kHit) != 0 || spread_holds) {
      if (!volatile_keys.empty()) volatile_keys.erase(key);  // (hashing costs, even when empty)
      update(key, hit_log);
    } else if ((e.roles & kMoverHit) != 0) {
      volatile_keys.insert(key);
      set_at_least_past(key, hit_log);
    } else if ((e.roles & kCrossed) != 0) {
      if (!volatile_keys.empty() && volatile_keys.erase(key) != 0)
        set_at_least_past(key, miss_log);  // where a mover was: free now
      else
        update(key, miss_log);
    }
  }
  // Settling walks the whole tree: run after every keyframe it was 13 % of the mapping thread's
  // time on Bonn crowd part1 (perf). It runs when the tree has doubled since it last ran, which
  // bounds the memory of the leaves not merged yet to the settled tree's, and on settle().
  if (tree.size() > 2 * settled_size) settle();
}

void OccupancyMap::Impl::settle() {
  tree.updateInnerOccupancy();
  // Lazy updates leave every voxel a leaf: merge the children that agree (free space at
  // clamp_min, mostly) into their parent.
  tree.prune();
  settled_size = tree.size();
}

void OccupancyMap::Impl::reintegrate_all() {
  Stopwatch watch;
  tree.clear();
  settled_size = 0;
  colours.clear();
  volatile_keys.clear();
  // No more helpers than keyframes beside the one this thread gathers.
  const auto helpers = static_cast<std::size_t>(std::max(0, options.rebuild_threads - 1));
  reintegrate_with_helpers(std::min(helpers, keyframes.empty() ? 0 : keyframes.size() - 1));
  ++rebuilds;
  last_rebuild_ms = watch.elapsed_ms();
  pending = false;
}

/// The keyframes' marks are gathered by this thread and `helpers` others (none: this thread
/// alone) into a ring of collectors (this thread's own and one per helper) and applied to the
/// octree in the keyframes' order by this thread: the same map as integrate() one after the
/// other.
void OccupancyMap::Impl::reintegrate_with_helpers(std::size_t helpers) {
  // Two collectors a thread: a helper gathers the next keyframes while this thread applies one
  // (applying takes about as long as gathering: with one a thread, this thread gathered half the
  // keyframes and applied all of them while the helper waited for a free collector).
  const std::size_t slots = helpers > 0 ? 2 * (helpers + 1) : 1;
  std::vector<detail::Collector> ring(slots);
  std::swap(ring[0], collector);  // its scratch space has grown already (a fresh one is valid too)
  detail::gather_and_apply_in_order(
      keyframes.size(), helpers, slots,
      [&](std::size_t k, std::size_t slot) { ring[slot].collect(tree, options, keyframes[k]); },
      [&](std::size_t, std::size_t slot) { apply(ring[slot]); });
  std::swap(ring[0], collector);
}

OccupancyMap::OccupancyMap(const OccupancyOptions& options) {
  if (auto problem = options.check()) throw InputError(*problem);
  impl_ = std::make_unique<Impl>(options);
}

OccupancyMap::~OccupancyMap() = default;

OccupancyMap OccupancyMap::clone() const {
  OccupancyMap copy(impl_->options);
  copy.impl_ = std::make_unique<Impl>(*impl_);
  copy.impl_->configure();
  return copy;
}
OccupancyMap::OccupancyMap(OccupancyMap&&) noexcept = default;
OccupancyMap& OccupancyMap::operator=(OccupancyMap&&) noexcept = default;

void OccupancyMap::insert(const KeyframeDepth& keyframe) {
  Stopwatch watch;
  KeyframeSamples samples = sample_keyframe(keyframe, impl_->options);
  // Before the keyframe is integrated: its own rays already free the first place of an object
  // that it is the first to see moving (on the synthetic pushed chair, often the one keyframe
  // that looks there after the push).
  if (impl_->options.use_masks) impl_->note_objects(keyframe);
  insert(std::move(samples));
  impl_->insert_ms.back() = watch.elapsed_ms();
}

std::optional<std::string> KeyframeSamples::check() const {
  if (auto problem = camera.check()) return problem;
  if (step < 1 || step > 64) return "the sample step must be in [1, 64]";
  const cv::Size size(camera.width / step, camera.height / step);
  if (depth_mm.type() != CV_16UC1 || depth_mm.size() != size || kind.type() != CV_8UC1 ||
      kind.size() != size ||
      (!colour.empty() && (colour.type() != CV_8UC3 || colour.size() != size)))
    return "samples that do not fit the camera: they must be CV_16UC1 depth, CV_8UC1 kinds (and "
           "CV_8UC3 colour) of the camera's size over the step, " +
           std::to_string(size.width) + "x" + std::to_string(size.height);
  return std::nullopt;
}

void OccupancyMap::integrate_transient(const KeyframeDepth& view) {
  Stopwatch watch;
  impl_->integrate_pending_keyframes();  // under the view, not over it
  impl_->integrate(sample_keyframe(view, impl_->options));
  impl_->insert_ms.push_back(watch.elapsed_ms());
}

void OccupancyMap::insert(KeyframeSamples samples) {
  Stopwatch watch;
  Impl& m = *impl_;
  if (auto problem = samples.check())
    throw InputError("keyframe " + std::to_string(samples.id) + ": " + *problem);
  const auto found = m.index.find(samples.id);
  if (found != m.index.end()) {
    m.keyframes[found->second] = std::move(samples);
    m.deferred ? void(m.pending = true) : m.reintegrate_all();
  } else {
    m.index.emplace(samples.id, m.keyframes.size());
    m.keyframes.push_back(std::move(samples));
    m.deferred ? void(m.pending = true) : m.integrate(m.keyframes.back());
  }
  m.insert_ms.push_back(watch.elapsed_ms());
}

namespace {

/// Whether a pose change moves the map by more than `tolerance` (metres) within `range`.
bool moved(const SE3& a, const SE3& b, double tolerance, double range) {
  const double shift = (a.translation() - b.translation()).norm();
  const double turn = rotation_angle(a.quaternion().conjugate() * b.quaternion()) * range;
  return shift > tolerance || turn > tolerance;
}

}  // namespace

bool OccupancyMap::correct(const std::unordered_map<KeyframeId, SE3>& T_w_c, bool listed_only) {
  Impl& m = *impl_;
  // The listed keyframes that are stored, by id, with their world motion (new * old^-1).
  std::map<KeyframeId, SE3> motions;
  for (const auto& [id, pose] : T_w_c) {
    const auto found = m.index.find(id);
    if (found != m.index.end())
      motions.emplace(id, pose * m.keyframes[found->second].T_w_c.inverse());
  }
  if (motions.empty()) return false;
  const double tolerance = m.options.rebuild_tolerance * m.options.resolution;
  bool any = false;
  for (auto& kf : m.keyframes) {
    SE3 pose;
    const auto listed = T_w_c.find(kf.id);
    if (listed != T_w_c.end()) {
      pose = listed->second;
    } else if (listed_only) {
      continue;
    } else {  // the closest earlier listed keyframe's motion; none earlier: it stays
      auto ref = motions.upper_bound(kf.id);
      if (ref == motions.begin()) continue;
      pose = std::prev(ref)->second * kf.T_w_c;
    }
    if (moved(kf.T_w_c, pose, tolerance, m.options.max_range)) any = true;
    kf.T_w_c = pose;
  }
  if (any) m.deferred ? void(m.pending = true) : m.reintegrate_all();
  return any;
}

void OccupancyMap::rebuild() { impl_->reintegrate_all(); }

bool OccupancyMap::pending() const { return impl_->pending; }

bool OccupancyMap::integrate_pending() { return impl_->integrate_pending_keyframes(); }

void OccupancyMap::settle() { impl_->settle(); }

VoxelState OccupancyMap::state(const Eigen::Vector3d& p) const {
  const octomap::OcTreeNode* node = impl_->tree.search(p.x(), p.y(), p.z());
  if (node == nullptr) return VoxelState::kUnknown;
  return impl_->tree.isNodeOccupied(node) ? VoxelState::kOccupied : VoxelState::kFree;
}

std::vector<OccupiedVoxel> OccupancyMap::occupied_voxels() const {
  const Impl& m = *impl_;
  std::vector<OccupiedVoxel> voxels;
  for (auto it = m.tree.begin_leafs(), end = m.tree.end_leafs(); it != end; ++it) {
    if (!m.tree.isNodeOccupied(*it)) continue;
    OccupiedVoxel v;
    const octomap::point3d c = it.getCoordinate();
    v.centre = {c.x(), c.y(), c.z()};
    v.size = it.getSize();
    const auto colour = m.colours.find(it.getKey());
    if (colour != m.colours.end() && colour->second.n > 0) {
      const ColourSum& s = colour->second;
      v.rgb = {static_cast<std::uint8_t>(s.r / s.n), static_cast<std::uint8_t>(s.g / s.n),
               static_cast<std::uint8_t>(s.b / s.n)};
      v.has_colour = true;
    }
    voxels.push_back(v);
  }
  std::sort(voxels.begin(), voxels.end(), [](const OccupiedVoxel& a, const OccupiedVoxel& b) {
    return std::tie(a.centre.z(), a.centre.y(), a.centre.x()) <
           std::tie(b.centre.z(), b.centre.y(), b.centre.x());
  });
  return voxels;
}

OccupancyStats OccupancyMap::stats() const {
  const Impl& m = *impl_;
  OccupancyStats s;
  s.keyframes = m.keyframes.size();
  const double res = m.tree.getResolution();
  for (auto it = m.tree.begin_leafs(), end = m.tree.end_leafs(); it != end; ++it) {
    ++s.leaf_nodes;
    const std::size_t n = detail::voxels_in_leaf(it.getSize(), res);
    (m.tree.isNodeOccupied(*it) ? s.occupied_voxels : s.free_voxels) += n;
  }
  s.integration_ms = compute_stats(m.insert_ms);
  s.integration = m.deferred ? "at_end" : "live";
  s.rebuilds = m.rebuilds;
  s.last_rebuild_ms = m.last_rebuild_ms;
  s.octree_bytes = m.tree.memoryUsage();
  for (const auto& kf : m.keyframes) s.keyframe_bytes += kf.bytes() + sizeof(KeyframeSamples);
  // An unordered_map node: the key, the value, the next pointer and the cached hash, and one
  // bucket pointer.
  s.colour_bytes = m.colours.size() * (sizeof(octomap::OcTreeKey) + sizeof(ColourSum) + 3 * 8);
  return s;
}

const OccupancyOptions& OccupancyMap::options() const { return impl_->options; }
const std::vector<KeyframeSamples>& OccupancyMap::keyframes() const { return impl_->keyframes; }
const octomap::OcTree& OccupancyMap::octree() const { return impl_->tree; }

}  // namespace mcslam::mapping
