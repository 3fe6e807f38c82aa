// Dynamic scenes with a crowd (SynthOptions::DynamicObjects::people > 1): the extra people's
// paths, how much of the image they take, the people the oracle misses, and the label images
// written next to a synthetic sequence.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "mcslam/core/error.hpp"
#include "mcslam/perception/detection.hpp"
#include "mcslam/synth/objects.hpp"
#include "mcslam/synth/sequence.hpp"
#include "support/temp_dir.hpp"
#include "synth/scene_geometry.hpp"

namespace mcslam::synth {
namespace {

namespace fs = std::filesystem;
using Dyn = SynthOptions::DynamicObjects;

constexpr int kPerson1 = 8;  // after the 8 static objects
constexpr int kCrowdChair = 9;
/// Scene::objects index of person `number` >= 2 when the chair is in the scene.
constexpr int crowd_index(int number) { return kCrowdChair + number - 1; }

/// 160 x 120 (the intrinsics of 640 x 480 scaled by 1/4), so that rendering stays cheap; image
/// fractions are those of 640 x 480 up to the pixel grid.
SynthOptions crowd_options(int people, int undetected = 0, int frames = 300) {
  SynthOptions o;
  o.width = 160;
  o.height = 120;
  o.fx = o.fy = 525.0 / 4.0;
  o.cx = 79.5;
  o.cy = 59.5;
  o.frames = frames;
  o.dynamic.enabled = true;
  o.dynamic.people = people;
  o.dynamic.undetected_people = undetected;
  return o;
}

/// For tests of the motion only: plain textures are faster to generate and do not change the
/// geometry.
Scene crowd_motion_scene_of(SynthOptions o) {
  o.texture = TextureLevel::kLow;
  return make_room_scene(o);
}

using mcslam::test::TempDir;
using test::distance_to;
using test::Obb;
using test::obb_of;
using test::within;

/// Whether any pixel of `mask` lies on the image border.
bool touches_border(const cv::Mat& mask) {
  return cv::countNonZero(mask.row(0)) > 0 || cv::countNonZero(mask.row(mask.rows - 1)) > 0 ||
         cv::countNonZero(mask.col(0)) > 0 || cv::countNonZero(mask.col(mask.cols - 1)) > 0;
}

std::vector<std::string> data_lines(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);)
    if (!line.empty() && line[0] != '#') lines.push_back(line);
  return lines;
}

// --- options -----------------------------------------------------------------------------------

TEST(CrowdOptions, DefaultsAndRanges) {
  const SynthOptions o;
  EXPECT_EQ(o.dynamic.people, 1);
  EXPECT_EQ(o.dynamic.undetected_people, 0);
  EXPECT_EQ(Dyn::kMaxPeople, 6);
  EXPECT_EQ(o.dynamic.people_in_scene(), 0);  // disabled
  for (int people = 0; people <= Dyn::kMaxPeople; ++people)
    for (int undetected = 0; undetected <= people; ++undetected)
      EXPECT_FALSE(crowd_options(people, undetected, 2).check().has_value())
          << people << " " << undetected;
  SynthOptions no_person = crowd_options(4);
  EXPECT_EQ(no_person.dynamic.people_in_scene(), 4);
  no_person.dynamic.person = false;
  EXPECT_EQ(no_person.dynamic.people_in_scene(), 0);
}

TEST(CrowdOptions, CheckNamesTheBadField) {
  struct Case {
    const char* field;
    int people, undetected;
  };
  const Case cases[] = {
      {"dynamic.people", -1, 0},           {"dynamic.people", Dyn::kMaxPeople + 1, 0},
      {"dynamic.undetected_people", 2, 3}, {"dynamic.undetected_people", 2, -1},
      {"dynamic.undetected_people", 0, 1},
  };
  for (const Case& c : cases) {
    for (bool enabled : {false, true}) {  // bad values are reported even when disabled
      SynthOptions o = crowd_options(c.people, c.undetected, 2);
      o.dynamic.enabled = enabled;
      const auto problem = o.check();
      ASSERT_TRUE(problem.has_value()) << c.field;
      EXPECT_NE(problem->find(c.field), std::string::npos) << *problem;
      // The message says what was given and what is allowed.
      EXPECT_NE(
          problem->find(
              "(got " +
              std::to_string(c.field == std::string("dynamic.people") ? c.people : c.undetected) +
              ")"),
          std::string::npos)
          << *problem;
      EXPECT_THROW(SyntheticSequence{o}, InputError) << c.field;
    }
  }
}

// --- the scene ---------------------------------------------------------------------------------

/// people = 1 is the dynamic scene as it was before crowds existed: the same objects and the same
/// renders (fingerprints measured with the code before the change, as in
/// DynamicScene.DisabledKeepsTheStaticRoom), and the crowd leaves person 1 and the chair alone.
TEST(CrowdScene, OnePersonIsTheSceneAsBefore) {
  const SynthOptions one = crowd_options(1);
  SynthOptions defaults = crowd_options(1);
  defaults.dynamic = Dyn{};
  defaults.dynamic.enabled = true;
  const SyntheticSequence seq(one);
  EXPECT_EQ(seq.scene().objects.size(), make_room_scene(defaults).objects.size());
  ASSERT_EQ(seq.scene().objects.size(), 10u);
  ASSERT_EQ(seq.scene().textures.size(), 16u);
  for (const SceneObject& object : seq.scene().objects) EXPECT_TRUE(object.detectable);

  struct Fingerprint {
    int frame;
    double b, g, r, depth;
    int labels[11];  // -1 (room), 0..9
  };
  const Fingerprint expected[] = {
      {0,
       88.449167,
       83.521719,
       91.743594,
       2.195638085,
       {7866, 4562, 592, 1165, 0, 0, 0, 0, 0, 4847, 168}},
      {60,
       92.548385,
       86.110000,
       88.919688,
       2.216225985,
       {12264, 4609, 734, 0, 0, 229, 0, 0, 0, 0, 1364}},
      {150,
       89.244010,
       81.004844,
       92.035104,
       2.575449164,
       {10767, 2561, 330, 942, 1007, 0, 0, 0, 0, 3593, 0}},
      {299,
       84.562813,
       80.709583,
       87.636354,
       2.155206737,
       {9445, 1547, 433, 2442, 0, 0, 0, 0, 0, 5333, 0}},
  };
  for (const Fingerprint& f : expected) {
    const RenderedFrame frame = seq.frame(f.frame);
    const cv::Scalar mean = cv::mean(frame.rgb);
    EXPECT_NEAR(mean[0], f.b, 0.01) << "frame " << f.frame;
    EXPECT_NEAR(mean[1], f.g, 0.01) << "frame " << f.frame;
    EXPECT_NEAR(mean[2], f.r, 0.01) << "frame " << f.frame;
    EXPECT_NEAR(cv::mean(frame.depth)[0], f.depth, 1e-6) << "frame " << f.frame;
    for (int k = -1; k < 10; ++k)
      EXPECT_EQ(cv::countNonZero(frame.labels == k), f.labels[k + 1])
          << "frame " << f.frame << " label " << k;
  }

  // With a crowd, the first ten objects (and their textures) are the same.
  const Scene crowd = crowd_motion_scene_of(crowd_options(Dyn::kMaxPeople));
  const Scene alone = crowd_motion_scene_of(crowd_options(1));
  ASSERT_EQ(crowd.objects.size(), 15u);
  for (std::size_t k = 0; k < alone.objects.size(); ++k) {
    EXPECT_EQ(crowd.objects[k].class_name, alone.objects[k].class_name);
    EXPECT_EQ(crowd.objects[k].half_extents, alone.objects[k].half_extents);
    EXPECT_EQ(crowd.objects[k].texture_id, alone.objects[k].texture_id);
    for (double t : {0.0, 1.5, 4.2, 9.9})
      EXPECT_EQ(
          (crowd.objects[k].pose_at(t).matrix() - alone.objects[k].pose_at(t).matrix()).norm(), 0.0)
          << "object " << k << " t " << t;
  }
  for (std::size_t i = 0; i < alone.textures.size(); ++i)
    for (std::size_t l = 0; l < alone.textures[i]->layers.size(); ++l)
      EXPECT_EQ(
          cv::norm(alone.textures[i]->layers[l][0], crowd.textures[i]->layers[l][0], cv::NORM_INF),
          0.0);

  // people = 0 is person = false: the chair moves up to index 8, and no person is left.
  SynthOptions zero = crowd_options(0);
  SynthOptions no_person = crowd_options(Dyn::kMaxPeople);
  no_person.dynamic.person = false;
  for (const SynthOptions& o : {zero, no_person}) {
    const Scene scene = crowd_motion_scene_of(o);
    ASSERT_EQ(scene.objects.size(), 9u);
    EXPECT_EQ(scene.objects[8].class_name, "chair");
  }
}

TEST(CrowdScene, EveryPersonIsAFreeMoverWithItsOwnTexture) {
  SynthOptions o = crowd_options(Dyn::kMaxPeople, 2);
  const Scene scene = make_room_scene(o);
  ASSERT_EQ(scene.objects.size(), 15u);
  std::vector<int> people = {kPerson1};
  for (int number = 2; number <= Dyn::kMaxPeople; ++number) people.push_back(crowd_index(number));
  EXPECT_EQ(scene.objects[kCrowdChair].class_name, "chair");
  for (std::size_t n = 0; n < people.size(); ++n) {
    const SceneObject& p = scene.objects[people[n]];
    EXPECT_EQ(p.class_name, "person");
    EXPECT_EQ(p.motion, MotionKind::kFree);
    // The last two are the ones the detector misses.
    EXPECT_EQ(p.detectable, n + 2 < people.size()) << "person " << n + 1;
    const double height = 2.0 * p.half_extents.z();
    EXPECT_GT(height, 1.4);
    EXPECT_LT(height, 1.9);
    // Its own texture: rich, and different from every other person's.
    const Texture& texture = *scene.textures.at(p.texture_id);
    ASSERT_EQ(texture.layers.size(), 6u);
    cv::Scalar mean, stddev;
    cv::meanStdDev(texture.layers[0][0], mean, stddev);
    EXPECT_GT(stddev[0] + stddev[1] + stddev[2], 30.0);
    for (std::size_t m = 0; m < n; ++m) {
      const SceneObject& q = scene.objects[people[m]];
      EXPECT_NE(p.texture_id, q.texture_id);
      const cv::Mat& a = texture.layers[0][0];
      const cv::Mat& b = scene.textures.at(q.texture_id)->layers[0][0];
      const cv::Rect common(0, 0, std::min(a.cols, b.cols), std::min(a.rows, b.rows));
      EXPECT_GT(cv::norm(a(common), b(common), cv::NORM_L1) / common.area(), 20.0)
          << "persons " << m + 1 << " and " << n + 1;
    }
  }
  // The motion does not depend on the seed (only textures and noise do).
  SynthOptions other_seed = o;
  other_seed.seed = 99;
  const Scene other = crowd_motion_scene_of(other_seed);
  for (int k : people)
    for (double t : {0.0, 2.0, 7.5})
      EXPECT_EQ(
          (scene.objects[k].pose_at(t).matrix() - other.objects[k].pose_at(t).matrix()).norm(),
          0.0);
}

/// Each crowd person is at rest until start_time, then starts smoothly (the motion_time ramp),
/// never exceeds person_speed, walks at its own pace, and keeps bobbing and leaning.
TEST(CrowdScene, StartAtRestThenWalkSmoothlyEachAtItsPace) {
  for (const auto& [person_speed, start] : {std::pair{1.0, 1.0}, std::pair{2.0, 0.0}}) {
    SynthOptions o = crowd_options(Dyn::kMaxPeople);
    o.dynamic.person_speed = person_speed;
    o.dynamic.start_time = start;
    const Scene scene = crowd_motion_scene_of(o);
    std::vector<double> peaks;
    for (int number = 2; number <= Dyn::kMaxPeople; ++number) {
      const SceneObject& p = scene.objects[crowd_index(number)];
      const SE3 rest = p.pose_at(-1.0);
      for (double t = -1.0; t <= start; t += 0.01)
        EXPECT_EQ((p.pose_at(t).matrix() - rest.matrix()).norm(), 0.0) << number << " t " << t;
      const double dt = 1e-3;
      double peak = 0.0, max_jump = 0.0, min_z = 1e9, max_z = -1e9, min_tilt = 90, max_tilt = 0;
      Eigen::Vector3d previous_v = Eigen::Vector3d::Zero();
      for (double t = start; t < start + 20.0; t += dt) {
        const Eigen::Vector3d a = p.pose_at(t).translation(), b = p.pose_at(t + dt).translation();
        const Eigen::Vector3d v = (b - a) / dt;
        peak = std::max(peak, v.head<2>().norm());
        max_jump = std::max(max_jump, (v - previous_v).norm());
        previous_v = v;
        min_z = std::min(min_z, a.z()), max_z = std::max(max_z, a.z());
        const double tilt = std::acos(std::clamp(p.pose_at(t).rotation()(2, 2), -1.0, 1.0));
        min_tilt = std::min(min_tilt, tilt), max_tilt = std::max(max_tilt, tilt);
      }
      EXPECT_LE(peak, person_speed * 1.0005) << "person " << number;
      EXPECT_GE(peak, 0.5 * person_speed) << "person " << number;
      EXPECT_LT(max_jump, 0.03 * std::max(1.0, person_speed * person_speed)) << number;
      EXPECT_GT(max_z - min_z, 0.3) << "person " << number << " bobs";
      EXPECT_GT((max_tilt - min_tilt) * 180.0 / 3.141592653589793, 4.0) << number << " leans";
      for (double seen : peaks) EXPECT_GT(std::abs(peak - seen), 0.02) << number << ": own pace";
      peaks.push_back(peak);
    }
  }
}

/// Every person stays in the room, clear of the furniture, the chair and each other, and the
/// crowd at least 0.4 m (the Kinect's nearest depth) from every camera position, over a long
/// stretch of the camera path (150 s), at several speeds and at person 1's and the chair's
/// extreme scales.
TEST(CrowdScene, ClearOfTheCameraTheRoomTheFurnitureAndEachOther) {
  struct Config {
    double person_scale, chair_scale, person_speed, chair_speed, camera_speed;
  };
  const Config configs[] = {
      {1.0, 1.0, 1.0, 0.5, 1.0},
      {Dyn::kMaxPersonScale, Dyn::kMaxChairScale, Dyn::kMaxSpeed, 0.1, 0.5},
      {Dyn::kMinScale, Dyn::kMinScale, 0.3, Dyn::kMaxSpeed, 2.0},
  };
  for (const Config& c : configs) {
    SynthOptions o = crowd_options(Dyn::kMaxPeople, 0, 30 * 150);
    o.dynamic.person_scale = c.person_scale;
    o.dynamic.chair_scale = c.chair_scale;
    o.dynamic.person_speed = c.person_speed;
    o.dynamic.chair_speed = c.chair_speed;
    o.speed = c.camera_speed;
    const Scene scene = crowd_motion_scene_of(o);
    const Trajectory path = camera_path(o);
    const int n = static_cast<int>(scene.objects.size());
    double min_camera = 1e9;
    int overlaps = 0, outside = 0;
    for (std::size_t i = 0; i < path.size(); ++i) {
      const double t = path[i].timestamp - 1.0;
      std::vector<Obb> boxes;
      for (const SceneObject& object : scene.objects) boxes.push_back(obb_of(object, t));
      for (int k = crowd_index(2); k < n; ++k) {
        min_camera = std::min(min_camera, distance_to(boxes[k], path[i].T_w_c.translation()));
        for (const Eigen::Vector3d& p : scene.objects[k].corners_at(t))
          if ((p.array() < scene.room_min.array()).any() ||
              (p.array() > scene.room_max.array()).any())
            ++outside;
        for (int j = 0; j < n; ++j)
          if (j != k && within(boxes[k], boxes[j], 0.02)) ++overlaps;
      }
    }
    std::printf(
        "person 1 scale %.1f, chair %.1f, people speed %.1f, camera %.1f: crowd at least %.2f m "
        "from the camera\n",
        c.person_scale, c.chair_scale, c.person_speed, c.camera_speed, min_camera);
    EXPECT_GE(min_camera, 0.4);
    EXPECT_EQ(overlaps, 0) << "a person comes within 2 cm of another object";
    EXPECT_EQ(outside, 0);
  }
}

// --- what the camera sees ----------------------------------------------------------------------

/// Over the default 300 frames: person 2 passes close in front of the camera and fills 40 % of
/// the image or more in some frames; person 3 is often cut by the image border. The measured
/// figures are printed.
TEST(CrowdScene, PersonTwoFillsTheImageAndPersonThreeIsCutByTheBorder) {
  const SynthOptions o = crowd_options(3);
  const SyntheticSequence seq(o);
  ASSERT_EQ(seq.scene().objects.size(), 12u);
  const int min_pixels = oracle_min_pixels(o.width, o.height);
  const double image = static_cast<double>(o.width) * o.height;
  struct Figures {
    int visible = 0, large = 0, cut = 0;
    double max_fraction = 0.0;
  };
  Figures figures[4];  // persons 1 .. 3
  const int index[4] = {-1, kPerson1, crowd_index(2), crowd_index(3)};
  for (int i = 0; i < seq.size(); ++i) {
    const RenderedFrame frame = seq.frame(i);
    for (int number = 1; number <= 3; ++number) {
      const cv::Mat mask = frame.labels == index[number];
      const int pixels = cv::countNonZero(mask);
      Figures& f = figures[number];
      f.max_fraction = std::max(f.max_fraction, pixels / image);
      if (pixels < min_pixels) continue;
      ++f.visible;
      f.large += pixels >= 0.4 * image;
      f.cut += touches_border(mask);
    }
  }
  for (int number = 1; number <= 3; ++number) {
    const Figures& f = figures[number];
    std::printf(
        "person %d: visible in %.0f%% of %d frames, max image fraction %.2f, >= 40%% of the image "
        "in %.1f%%, cut by the border in %.0f%% of the frames (%d)\n",
        number, 100.0 * f.visible / seq.size(), seq.size(), f.max_fraction,
        100.0 * f.large / seq.size(), 100.0 * f.cut / seq.size(), f.cut);
  }
  const int n = seq.size();
  EXPECT_GE(figures[2].visible, n / 4);
  EXPECT_GE(figures[2].large, n / 20);
  EXPECT_GE(figures[2].max_fraction, 0.4);
  EXPECT_GE(figures[3].visible, n / 5);
  EXPECT_GE(figures[3].cut, n / 5);
  // Person 1 is still seen often, though person 2 passes in front of it.
  EXPECT_GE(figures[1].visible, n * 4 / 10);
}

/// The last undetected_people people get no oracle box, but their pixels are labelled; the
/// others' boxes are unchanged.
TEST(CrowdScene, UndetectedPeopleHaveLabelsButNoBoxes) {
  const SyntheticSequence all(crowd_options(3, 0, 300));
  const SyntheticSequence missed(crowd_options(3, 1, 300));
  EXPECT_TRUE(missed.scene().objects[kPerson1].detectable);
  EXPECT_TRUE(missed.scene().objects[crowd_index(2)].detectable);
  EXPECT_FALSE(missed.scene().objects[crowd_index(3)].detectable);
  const int min_pixels = oracle_min_pixels(160, 120);
  int labelled = 0;
  for (int i = 0; i < all.size(); i += 5) {
    const RenderedFrame a = all.frame(i), b = missed.frame(i);
    EXPECT_EQ(cv::norm(a.labels, b.labels, cv::NORM_INF), 0.0) << "same scene, same labels";
    const int pixels = cv::countNonZero(b.labels == crowd_index(3));
    const perception::FrameDetections da = all.oracle_detections(i, a);
    const perception::FrameDetections db = missed.oracle_detections(i, b);
    // The same boxes but person 3's (the last person box of the frame when it is seen).
    std::vector<perception::Detection> expected = da.detections;
    if (pixels >= min_pixels) {
      ++labelled;
      const cv::Rect r = cv::boundingRect(b.labels == crowd_index(3));
      const auto it = std::find_if(expected.begin(), expected.end(), [&](const auto& d) {
        return d.class_name == "person" && d.box == cv::Rect2f(r);
      });
      ASSERT_NE(it, expected.end()) << "frame " << i;
      expected.erase(it);
    }
    ASSERT_EQ(db.detections.size(), expected.size()) << "frame " << i;
    for (std::size_t k = 0; k < expected.size(); ++k) {
      EXPECT_EQ(db.detections[k].class_name, expected[k].class_name);
      EXPECT_EQ(db.detections[k].box, expected[k].box);
    }
  }
  EXPECT_GE(labelled, 10) << "person 3 is seen (labelled) in many frames";

  // All three missed: no person box at all, though they are in view.
  const SyntheticSequence none(crowd_options(3, 3, 300));
  int people_pixels = 0;
  for (int i = 0; i < none.size(); i += 10) {
    const RenderedFrame frame = none.frame(i);
    for (int k : {kPerson1, crowd_index(2), crowd_index(3)})
      people_pixels += cv::countNonZero(frame.labels == k);
    for (const perception::Detection& d : none.oracle_detections(i, frame).detections)
      EXPECT_NE(d.class_name, "person") << "frame " << i;
  }
  EXPECT_GT(people_pixels, 0);
}

// --- files -------------------------------------------------------------------------------------

/// labels.txt and labels/<t>.png hold exactly RenderedFrame::labels (index + 1, 0 for the room);
/// objects.json flags the missed person; nothing of it is left by a static sequence.
TEST(CrowdFiles, LabelImagesRoundTripAndObjectsJsonFlagsTheMissedPeople) {
  const TempDir tmp;
  SynthOptions o = crowd_options(3, 1, 8);
  o.dynamic.start_time = 0.0;
  o.readout_time = 0.02;  // labels are per row like the images
  const fs::path dir = tmp.path() / "crowd";
  write_sequence(dir.string(), o);
  const SyntheticSequence seq(o);

  const std::vector<std::string> lines = data_lines(dir / "labels.txt");
  ASSERT_EQ(lines.size(), 8u);
  std::set<int> seen;
  for (int i = 0; i < seq.size(); ++i) {
    std::istringstream line(lines[i]);
    std::string stamp, file;
    line >> stamp >> file;
    EXPECT_NEAR(std::stod(stamp), seq.timestamp(i), 1e-6);
    EXPECT_EQ(file, "labels/" + stamp + ".png");
    const cv::Mat raw = cv::imread((dir / file).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(raw.type(), CV_16UC1) << file;
    ASSERT_EQ(raw.size(), cv::Size(160, 120));
    const RenderedFrame frame = seq.frame(i);
    cv::Mat expected;
    frame.labels.convertTo(expected, CV_16UC1, 1.0, 1.0);
    EXPECT_EQ(cv::norm(raw, expected, cv::NORM_INF), 0.0) << file;
    const cv::Mat back = read_label_image((dir / file).string());
    ASSERT_EQ(back.type(), CV_16SC1);
    EXPECT_EQ(cv::norm(back, frame.labels, cv::NORM_INF), 0.0) << file;
    for (int k = -1; k < 12; ++k)
      if (cv::countNonZero(back == k) > 0) seen.insert(k);
  }
  EXPECT_TRUE(seen.count(-1) > 0 && seen.size() >= 3) << "the room and some objects in view";

  // objects.json: one entry per person, the missed one flagged; detections.json without it.
  std::ifstream in(dir / "objects.json");
  const nlohmann::json j = nlohmann::json::parse(in);
  const auto& objects = j.at("objects");
  ASSERT_EQ(objects.size(), 12u);
  int people = 0;
  for (std::size_t k = 0; k < objects.size(); ++k) {
    people += objects[k].at("class") == "person";
    EXPECT_EQ(objects[k].at("detected").get<bool>(), static_cast<int>(k) != crowd_index(3)) << k;
  }
  EXPECT_EQ(people, 3);
  EXPECT_EQ(objects[crowd_index(3)].at("motion"), "free");
  ASSERT_EQ(j.at("frames").size(), 8u);
  EXPECT_EQ(j.at("frames")[0].at("objects").size(), 12u);
  const perception::DetectionsFile detections =
      perception::read_detections((dir / "detections.json").string());
  ASSERT_EQ(detections.frames.size(), 8u);
  for (int i = 0; i < seq.size(); ++i) {
    const perception::FrameDetections expected = seq.oracle_detections(i, seq.frame(i));
    ASSERT_EQ(detections.frames[i].detections.size(), expected.detections.size());
  }

  // A shorter dynamic run in the same folder leaves no stale label image behind; a static run
  // removes them all (and objects.json), but not another file a user keeps in labels/.
  SynthOptions shorter = o;
  shorter.frames = 3;
  write_sequence(dir.string(), shorter);
  EXPECT_EQ(data_lines(dir / "labels.txt").size(), 3u);
  int pngs = 0;
  for (const auto& entry : fs::directory_iterator(dir / "labels")) pngs += entry.is_regular_file();
  EXPECT_EQ(pngs, 3);

  SynthOptions plain = o;
  plain.dynamic.enabled = false;
  write_sequence(dir.string(), plain);
  EXPECT_FALSE(fs::exists(dir / "labels.txt"));
  EXPECT_FALSE(fs::exists(dir / "labels"));
  EXPECT_FALSE(fs::exists(dir / "objects.json"));

  write_sequence(dir.string(), shorter);
  {
    std::ofstream note(dir / "labels" / "notes.txt");
    note << "mine\n";
  }
  write_sequence(dir.string(), plain);
  EXPECT_FALSE(fs::exists(dir / "labels.txt"));
  EXPECT_TRUE(fs::exists(dir / "labels" / "notes.txt"));
  for (const auto& entry : fs::directory_iterator(dir / "labels"))
    EXPECT_NE(entry.path().extension(), ".png");
}

TEST(CrowdFiles, ReadLabelImageRejectsOtherImages) {
  const TempDir tmp;
  fs::create_directories(tmp.path());
  EXPECT_THROW(read_label_image((tmp.path() / "missing.png").string()), InputError);
  const fs::path colour = tmp.path() / "colour.png";
  cv::imwrite(colour.string(), cv::Mat(4, 4, CV_8UC3, cv::Scalar(1, 2, 3)));
  try {
    read_label_image(colour.string());
    ADD_FAILURE() << "accepted a colour image";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("16-bit"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace mcslam::synth
