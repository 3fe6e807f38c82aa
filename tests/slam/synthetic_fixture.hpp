#pragma once
// Rendered synthetic sequences shared by the SLAM tests (rendering dominates their run time).

#include <map>
#include <memory>
#include <tuple>
#include <vector>

#include "mcslam/eval/metrics.hpp"
#include "mcslam/slam/system.hpp"
#include "mcslam/synth/objects.hpp"
#include "mcslam/synth/sequence.hpp"

namespace mcslam::test {

struct RenderedSequence {
  synth::SynthOptions options;
  std::vector<synth::RenderedFrame> frames;
  Trajectory groundtruth;
  PinholeCamera camera;
};

/// Renders every frame of `options`.
inline std::unique_ptr<RenderedSequence> render(const synth::SynthOptions& options) {
  auto s = std::make_unique<RenderedSequence>();
  s->options = options;
  synth::SyntheticSequence seq(options);
  for (int i = 0; i < seq.size(); ++i) s->frames.push_back(seq.frame(i));
  s->groundtruth = seq.groundtruth();
  s->camera = seq.camera();
  return s;
}

/// Renders (once per process) `frames` frames of the synthetic room.
inline const RenderedSequence& rendered_sequence(
    int frames, bool depth_noise, double speed = 1.0, std::uint64_t seed = 1,
    synth::TextureLevel texture = synth::TextureLevel::kRich) {
  static std::map<std::tuple<int, bool, double, std::uint64_t, synth::TextureLevel>,
                  std::unique_ptr<RenderedSequence>>
      cache;
  auto& slot = cache[{frames, depth_noise, speed, seed, texture}];
  if (!slot) {
    synth::SynthOptions o;
    o.frames = frames;
    o.depth_noise = depth_noise;
    o.speed = speed;
    o.seed = seed;
    o.texture = texture;
    slot = render(o);
  }
  return *slot;
}

/// A rendered dynamic scene with its per-frame ground truth and oracle boxes.
struct DynamicSequence {
  synth::SynthOptions options;
  std::vector<synth::RenderedFrame> frames;
  std::vector<std::vector<synth::ObjectState>> states;  ///< per frame, per scene object
  perception::DetectionsFile detections;                ///< the oracle's boxes
  Trajectory groundtruth;
  PinholeCamera camera;
  std::vector<bool> undetected;  ///< per scene object: never reported by the oracle
};

/// Renders every frame of `options` (a dynamic scene) with its object states and oracle boxes.
inline std::unique_ptr<DynamicSequence> render_dynamic(const synth::SynthOptions& options) {
  auto s = std::make_unique<DynamicSequence>();
  s->options = options;
  synth::SyntheticSequence seq(options);
  for (int i = 0; i < seq.size(); ++i) {
    s->frames.push_back(seq.frame(i));
    s->states.push_back(seq.object_states(i, s->frames.back()));
    s->detections.frames.push_back(seq.oracle_detections(i, s->frames.back()));
  }
  s->groundtruth = seq.groundtruth();
  s->camera = seq.camera();
  for (const auto& object : seq.scene().objects) s->undetected.push_back(!object.detectable);
  return s;
}

/// What a run of the whole system on rendered frames gives.
struct SystemRun {
  std::vector<slam::FrameResult> frames;
  double ate = 0.0;  ///< ATE RMSE (metres) of System::trajectory() against the ground truth
  int tracked = 0;   ///< frames in state kOk
};

/// Runs the system on `frames` (timestamps from `groundtruth`), with boxes from `boxes` when
/// given (each frame waits for its own), and scores the trajectory.
inline SystemRun run_system(const std::vector<synth::RenderedFrame>& frames,
                            const Trajectory& groundtruth, const PinholeCamera& camera,
                            const slam::SystemOptions& options,
                            const perception::DetectionsFile* boxes) {
  slam::System system(camera, options);
  if (boxes)
    system.set_detection_source(std::make_unique<slam::FileDetectionSource>(*boxes, "oracle"),
                                true);
  SystemRun r;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    r.frames.push_back(system.process(frames[i].rgb, frames[i].depth, groundtruth[i].timestamp));
    r.tracked += r.frames.back().state == slam::TrackingState::kOk ? 1 : 0;
  }
  system.finish();
  r.ate = eval::evaluate(groundtruth, system.trajectory()).ate.translation.rmse;
  return r;
}

}  // namespace mcslam::test
