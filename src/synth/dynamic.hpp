#pragma once
// The moving objects of dynamic scenes (private to the synth module; see make_room_scene).

#include "mcslam/synth/scene.hpp"

namespace mcslam::synth::detail {

/// An object's motion time at scene time t: 0 until start_time, then a smooth ramp (rate
/// 3 v^2 - 2 v^3 of the elapsed fraction v of SynthOptions::DynamicObjects::kRampTime, so
/// velocity and acceleration start at 0), then speed * (t - start_time - kRampTime / 2).
double motion_time(double t, double start_time, double speed);

/// The person and the chair of make_room_scene: class name, half extents, motion kind and
/// pose_at (texture_id is left to the caller).
SceneObject make_person(const SynthOptions::DynamicObjects& options);
SceneObject make_chair(const SynthOptions::DynamicObjects& options);
/// Person `number` (2 .. SynthOptions::DynamicObjects::kMaxPeople) of the crowd of
/// make_room_scene: class name, half extents, motion kind and pose_at (texture_id and
/// detectable are left to the caller).
SceneObject make_crowd_person(int number, const SynthOptions::DynamicObjects& options);

}  // namespace mcslam::synth::detail
