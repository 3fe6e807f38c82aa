#include "mcslam/mapping/worker.hpp"

#include <utility>

#include "mcslam/core/thread_failure.hpp"
#include "mcslam/core/thread_priority.hpp"
#include "mcslam/core/worker.hpp"
#include "mcslam/mapping/floor.hpp"

namespace mcslam::mapping {

MappingWorker::MappingWorker(const OccupancyOptions& options, const std::string& thread_name)
    : map_(options),
      failure_(std::make_unique<ThreadFailure>("mapping (" + thread_name + ")")),
      worker_(std::make_unique<Worker>(thread_name)) {
  if (options.niceness > 0) {
    const int niceness = options.niceness;
    worker_->post([niceness] { lower_current_thread_priority(niceness); });  // best effort
  }
}

MappingWorker::~MappingWorker() { worker_.reset(); }

void MappingWorker::post_guarded(std::function<void()> body) {
  ++pending_;
  worker_->post([this, body = std::move(body)] {
    // The thread body: an exception is kept, never let out, and stops the work that follows.
    if (!failure_->failed()) {
      try {
        body();
      } catch (...) {
        failure_->set(std::current_exception());
      }
    }
    --pending_;
  });
}

void MappingWorker::run(const std::function<void(OccupancyMap&)>& job) {
  post_guarded([this, job] {
    const std::lock_guard<std::mutex> lock(map_mutex_);
    job(map_);
    ++version_;
  });
}

void MappingWorker::enqueue(const KeyframeDepth& keyframe) {
  if (!worker_ || failure_->failed()) return;  // finished or failed: dropped
  auto copy = std::make_shared<KeyframeDepth>(keyframe);
  copy->depth = keyframe.depth.clone();
  copy->dynamic_mask = keyframe.dynamic_mask.clone();
  copy->mover_mask = keyframe.mover_mask.clone();
  copy->colour = keyframe.colour.clone();
  run([copy](OccupancyMap& map) { map.insert(*copy); });
}

void MappingWorker::enqueue_shared(KeyframeDepth keyframe) {
  if (!worker_ || failure_->failed()) return;  // finished or failed: dropped
  auto shared = std::make_shared<KeyframeDepth>(std::move(keyframe));
  run([shared](OccupancyMap& map) { map.insert(*shared); });
}

void MappingWorker::restore(std::vector<KeyframeSamples> keyframes) {
  if (!worker_ || failure_->failed()) return;  // finished or failed: dropped
  auto shared = std::make_shared<std::vector<KeyframeSamples>>(std::move(keyframes));
  run([shared](OccupancyMap& map) {
    for (KeyframeSamples& kf : *shared) map.insert(std::move(kf));
  });
}

void MappingWorker::enqueue_transient(KeyframeDepth view) {
  if (!worker_ || failure_->failed()) return;  // finished or failed: dropped
  auto shared = std::make_shared<KeyframeDepth>(std::move(view));
  run([shared](OccupancyMap& map) { map.integrate_transient(*shared); });
}

void MappingWorker::correct(std::unordered_map<KeyframeId, SE3> T_w_c, bool listed_only) {
  if (!worker_ || failure_->failed()) return;  // finished or failed: dropped
  auto poses = std::make_shared<std::unordered_map<KeyframeId, SE3>>(std::move(T_w_c));
  post_guarded([this, poses, listed_only] {
    change_off_lock([&](OccupancyMap& map) { map.correct(*poses, listed_only); });
  });
}

void MappingWorker::change_off_lock(const std::function<void(OccupancyMap&)>& change) {
  OccupancyMap changed = map_.clone();
  change(changed);
  const std::lock_guard<std::mutex> lock(map_mutex_);
  map_ = std::move(changed);
  ++version_;
}

void MappingWorker::set_floor(std::optional<FloorPlane> floor) {
  const std::lock_guard<std::mutex> lock(map_mutex_);
  floor_ = floor;
  cached_.reset();
}

void MappingWorker::set_floor_candidates(std::vector<FloorPlane> candidates) {
  auto shared = std::make_shared<std::vector<FloorPlane>>(std::move(candidates));
  auto apply = [this, shared] {
    const std::lock_guard<std::mutex> lock(map_mutex_);
    floor_candidates_ = std::move(*shared);
    cached_.reset();
  };
  // Queued behind the keyframes before it: the caller (the sparse mapper's thread, once per
  // keyframe) never waits for an integration to let go of the map.
  if (!worker_ || failure_->failed())
    apply();
  else
    post_guarded(std::move(apply));
}

std::shared_ptr<const OccupancySnapshot> MappingWorker::snapshot() const {
  const std::lock_guard<std::mutex> lock(map_mutex_);
  if (cached_ && cached_->version == version_) return cached_;
  auto s = std::make_shared<OccupancySnapshot>();
  s->version = version_;
  s->grid = map_.grid(floor_ ? floor_ : choose_floor(map_, floor_candidates_));
  s->voxels = map_.occupied_voxels();
  s->stats = map_.stats();
  cached_ = std::move(s);
  return cached_;
}

void MappingWorker::with_map(const std::function<void(const OccupancyMap&)>& fn) const {
  const std::lock_guard<std::mutex> lock(map_mutex_);
  fn(map_);
}

std::size_t MappingWorker::pending() const { return pending_.load(); }

void MappingWorker::settle() {
  if (!worker_ || failure_->failed()) return;
  post_guarded([this] {
    if (map_.pending()) {  // integration "at_end": off the lock, as correct() rebuilds
      change_off_lock([](OccupancyMap& map) {
        map.integrate_pending();
        map.settle();
      });
      return;
    }
    // The same voxels in fewer nodes: no new version, but the next snapshot is built anew (its
    // node count and memory changed).
    const std::lock_guard<std::mutex> lock(map_mutex_);
    map_.settle();
    cached_.reset();
  });
}

void MappingWorker::wait() {
  settle();
  if (worker_) worker_->wait();
  failure_->throw_if_failed();
}

void MappingWorker::finish() {
  settle();
  worker_.reset();  // runs what is queued, then joins
  failure_->throw_if_failed();
}

bool MappingWorker::failed() const { return failure_->failed(); }
std::string MappingWorker::failure_message() const { return failure_->message(); }

}  // namespace mcslam::mapping
