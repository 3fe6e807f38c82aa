// The whole system on a rendered crowd (synth::SynthOptions::DynamicObjects::people): people
// walk through the room (persons 1-4: person 2 passes close enough to fill up to 57 % of the
// image, persons 3 and 4 are cut by its border), and the last one never gets a box from the
// oracle detector. The label images
// give every feature its ground truth, so the exclusion of the movers is measured feature by
// feature: precision (static features kept) and recall (features on moving people excluded),
// for the detected people and for the one found without a box.
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <string>

#include "mcslam/eval/metrics.hpp"
#include "mcslam/slam/system.hpp"
#include "mcslam/synth/objects.hpp"
#include "mcslam/synth/sequence.hpp"
#include "synthetic_fixture.hpp"

namespace mcslam {
namespace {

constexpr int kPeople = 4;
constexpr int kUndetected = 1;

using CrowdScene = test::DynamicSequence;

/// 300 frames (10 s) of the room with `people` walking (and the sliding chair), Kinect-like depth
/// noise; everyone starts moving at 1 s. people = 0 is the same room, camera path and chair.
std::unique_ptr<CrowdScene> render(int people, int undetected) {
  synth::SynthOptions options;
  options.frames = 300;
  options.depth_noise = true;
  options.seed = 1;
  options.dynamic.enabled = true;
  options.dynamic.people = people;
  options.dynamic.person = people > 0;
  options.dynamic.undetected_people = undetected;
  return test::render_dynamic(options);
}

const CrowdScene& crowd() {
  static const std::unique_ptr<CrowdScene> s = render(kPeople, kUndetected);
  return *s;
}

using RunResult = test::SystemRun;

RunResult run(const CrowdScene& s) {
  slam::SystemOptions options;
  options.sequential = true;
  return test::run_system(s.frames, s.groundtruth, s.camera, options, &s.detections);
}

/// The same room, camera path and chair without people, run once for every test.
const RunResult& empty_room() {
  static const RunResult r = [] {
    const RunResult run_result = run(*render(0, 0));
    std::printf("no people: ATE %.4f m, tracked %d\n", run_result.ate, run_result.tracked);
    return run_result;
  }();
  return r;
}

/// Feature counts over the tracked frames, by ground truth (the label under the keypoint, which
/// must be the same over its 3 x 3 neighbourhood: a keypoint on an object's outline sees both
/// sides and is left out of both counts).
struct Counts {
  int moving = 0, moving_excluded = 0;          // on a moving person (detected or not)
  int undetected = 0, undetected_excluded = 0;  // on a moving person without a box
  int fixed = 0, fixed_kept = 0;                // on the room or a static object
  double recall() const { return moving == 0 ? 0.0 : double(moving_excluded) / moving; }
  double undetected_recall() const {
    return undetected == 0 ? 0.0 : double(undetected_excluded) / undetected;
  }
  double kept() const { return fixed == 0 ? 0.0 : double(fixed_kept) / fixed; }
};

Counts count(const CrowdScene& s, const RunResult& r) {
  Counts c;
  for (std::size_t i = 0; i < s.frames.size(); ++i) {
    const slam::FrameResult& f = r.frames[i];
    if (f.state != slam::TrackingState::kOk || !f.frame_features) continue;
    const cv::Mat& labels = s.frames[i].labels;
    const auto& points = f.frame_features->points;
    for (std::size_t k = 0; k < points.size(); ++k) {
      const int u = static_cast<int>(std::lround(points[k].keypoint.uv.x()));
      const int v = static_cast<int>(std::lround(points[k].keypoint.uv.y()));
      if (u < 1 || v < 1 || u >= labels.cols - 1 || v >= labels.rows - 1) continue;
      const int label = labels.at<std::int16_t>(v, u);
      bool uniform = true;
      for (int dv = -1; dv <= 1; ++dv)
        for (int du = -1; du <= 1; ++du)
          uniform = uniform && labels.at<std::int16_t>(v + dv, u + du) == label;
      if (!uniform) continue;
      const bool excluded =
          k < f.point_labels.size() && f.point_labels[k] == slam::FeatureLabel::kDynamic;
      if (label < 0 || s.states[i][label].motion == synth::MotionKind::kStatic) {
        ++c.fixed;
        c.fixed_kept += excluded ? 0 : 1;
        continue;
      }
      const synth::ObjectState& truth = s.states[i][label];
      if (truth.class_name != "person" || !truth.moving) continue;
      ++c.moving;
      c.moving_excluded += excluded ? 1 : 0;
      if (s.undetected[label]) {
        ++c.undetected;
        c.undetected_excluded += excluded ? 1 : 0;
      }
    }
  }
  return c;
}

// One test: rendering the two scenes and running the system dominate.
TEST(CrowdSlam, MovingPeopleAreLeftOutStaticFeaturesKeptAndTheTrajectoryHolds) {
  const CrowdScene& s = crowd();
  const RunResult r = run(s);
  const Counts c = count(s, r);
  std::printf(
      "crowd: ATE %.4f m, tracked %d/%zu; moving-person features %d, excluded %.3f; "
      "undetected person %d, excluded %.3f; static features %d, kept %.3f\n",
      r.ate, r.tracked, s.frames.size(), c.moving, c.recall(), c.undetected, c.undetected_recall(),
      c.fixed, c.kept());
  EXPECT_EQ(r.tracked, static_cast<int>(s.frames.size()));
  EXPECT_GT(c.moving, 5000);
  EXPECT_GE(c.recall(), 0.95);
  EXPECT_GE(c.kept(), 0.85);
  // The person without a box (person 4, at the image border) is in view on a few frames only;
  // find_movers() does not find it there (see README, Status: the undetected movers' share is
  // printed, not asserted). The scene must hold it all the same.
  EXPECT_GT(c.undetected, 50);

  EXPECT_LE(r.ate, 1.5 * empty_room().ate)
      << "crowd " << r.ate << " m, no people " << empty_room().ate << " m";
}

// Three people; the third has no box and walks in from the right border until it fills 45 % of
// the image (frames 165-265), while a boxed person fills another third. Its features are young
// landmarks and last-frame points: the pose from the established landmarks keeps them out
// (TrackerOptions::established_age); without that, measured 0.229 m (69x the empty room). The
// person is a box: its front is a frame plane, which a region of motion now joins once the
// plane is seen to move, and the region's box then grows over it as the person walks in
// (ObjectHandler::find_movers, grow_movers). Before that, 0.0070 m (2.03x; fewer than 10
// established landmarks in view for about five frames, and everything entered at once); with
// it, 0.0050 m (1.43x). The goal is 2x.
TEST(CrowdSlam, AnUndetectedPersonFillingHalfTheViewDoesNotDragThePose) {
  const RunResult r = run(*render(3, 1));
  std::printf("undetected person filling 45 %%: ATE %.4f m, tracked %d; no people %.4f m\n", r.ate,
              r.tracked, empty_room().ate);
  EXPECT_EQ(r.tracked, 300);
  EXPECT_LE(r.ate, 2.0 * empty_room().ate);
}

}  // namespace
}  // namespace mcslam
