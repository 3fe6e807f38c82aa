#pragma once
// The low-texture synthetic room (plain surfaces, geometric edges), built once per test process.

#include "mcslam/synth/sequence.hpp"

namespace mcslam::test {

inline const synth::SyntheticSequence& low_texture_sequence() {
  static const synth::SyntheticSequence seq = [] {
    synth::SynthOptions o;
    o.texture = synth::TextureLevel::kLow;
    return synth::SyntheticSequence(o);
  }();
  return seq;
}

}  // namespace mcslam::test
