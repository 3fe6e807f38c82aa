#pragma once
// Rendered synthetic sequences shared by the SLAM tests (rendering dominates their run time).

#include <map>
#include <memory>
#include <tuple>
#include <vector>

#include "mcslam/synth/sequence.hpp"

namespace mcslam::test {

struct RenderedSequence {
  synth::SynthOptions options;
  std::vector<synth::RenderedFrame> frames;
  Trajectory groundtruth;
  PinholeCamera camera;
};

/// Renders (once per process) `frames` frames of the synthetic room.
inline const RenderedSequence& rendered_sequence(
    int frames, bool depth_noise, double speed = 1.0, std::uint64_t seed = 1,
    synth::TextureLevel texture = synth::TextureLevel::kRich) {
  static std::map<std::tuple<int, bool, double, std::uint64_t, synth::TextureLevel>,
                  std::unique_ptr<RenderedSequence>>
      cache;
  auto& slot = cache[{frames, depth_noise, speed, seed, texture}];
  if (!slot) {
    slot = std::make_unique<RenderedSequence>();
    slot->options.frames = frames;
    slot->options.depth_noise = depth_noise;
    slot->options.speed = speed;
    slot->options.seed = seed;
    slot->options.texture = texture;
    synth::SyntheticSequence seq(slot->options);
    for (int i = 0; i < seq.size(); ++i) slot->frames.push_back(seq.frame(i));
    slot->groundtruth = seq.groundtruth();
    slot->camera = seq.camera();
  }
  return *slot;
}

}  // namespace mcslam::test
