#pragma once
// The tracker, the local mapper and (with a vocabulary) the loop closer on one map, driven frame
// by frame without System: the pieces on their own, for their tests.

#include <memory>
#include <opencv2/imgproc.hpp>

#include "mcslam/slam/frame.hpp"
#include "mcslam/slam/local_mapper.hpp"
#include "mcslam/slam/loop_closer.hpp"
#include "mcslam/slam/tracker.hpp"
#include "synthetic_fixture.hpp"

namespace mcslam::test {

/// Everything runs inline: the mapper processes each keyframe request at once, then the loop
/// closer (when there is one) looks at the new keyframe. Every frame has (empty) detections, so
/// that the search for movers without a box (dynamics.find_movers) runs.
struct Pipeline {
  explicit Pipeline(const RenderedSequence& seq,
                    const slam::SystemOptions& o = slam::SystemOptions{},
                    std::shared_ptr<const place::Vocabulary> vocabulary = nullptr)
      : seq(seq),
        options(o),
        builder(seq.camera, options),
        tracker(seq.camera, options.tracker, map, vocabulary, options.place.direct_levels_up),
        mapper(seq.camera, options.mapper, options.tracker,
               options.tracker.close_depth_factor * seq.camera.bf / seq.camera.fx, map) {
    if (vocabulary) {
      mapper.set_vocabulary(vocabulary, options.place.direct_levels_up);
      loops = std::make_unique<slam::LoopCloser>(seq.camera, options.place.loop, options.tracker,
                                                 options.mapper, vocabulary, map, mapper);
    }
  }

  slam::Frame frame(int i) const {
    const auto& f = seq.frames[static_cast<std::size_t>(i)];
    cv::Mat gray;
    cv::cvtColor(f.rgb, gray, cv::COLOR_BGR2GRAY);
    slam::Frame frame =
        builder.build(static_cast<std::uint64_t>(i),
                      seq.groundtruth[static_cast<std::size_t>(i)].timestamp, gray, f.depth);
    frame.objects = std::make_shared<const slam::FrameObjects>();
    return frame;
  }

  /// Tracks frame i; a keyframe request goes to the mapper (and the keyframe to the loop
  /// closer) unless `hold` keeps it back.
  slam::TrackingOutcome track(int i, bool hold = false) {
    slam::TrackingOutcome out = tracker.track(frame(i), true, 0);
    if (out.keyframe && !hold) {
      const map::KeyFrameId id = out.keyframe->id;
      mapper.process(std::move(*out.keyframe));
      if (loops && map.keyframe(id) != nullptr) loops->process(id);
    }
    return out;
  }

  const RenderedSequence& seq;
  slam::SystemOptions options;
  map::Map map;
  slam::FrameBuilder builder;
  slam::Tracker tracker;
  slam::LocalMapper mapper;
  std::unique_ptr<slam::LoopCloser> loops;
};

}  // namespace mcslam::test
