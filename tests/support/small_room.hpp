#pragma once
// The synthetic room rendered at 320 x 240 (a quarter of the pixels, same field of view): for
// tests that need whole runs but not full-size images.

#include "mcslam/synth/scene.hpp"

namespace mcslam::test {

inline synth::SynthOptions small_room(int frames) {
  synth::SynthOptions o;
  o.width = 320;
  o.height = 240;
  o.fx = o.fy = 262.5;
  o.cx = 159.5;
  o.cy = 119.5;
  o.frames = frames;
  return o;
}

}  // namespace mcslam::test
