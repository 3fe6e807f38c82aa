// Feeds the frames of a TUM-layout folder to mcslam and prints the poses (TUM rows on stdout).
//   embed SEQ_DIR [SETTINGS_FILE]
#include <cstdio>
#include <iostream>
#include <mcslam/mcslam.hpp>

int main(int argc, char** argv) {
  if (argc < 2 || argc > 3) {
    std::cerr << "usage: embed SEQ_DIR [SETTINGS_FILE]\n";
    return 2;
  }
  try {
    const mcslam::Sequence sequence = mcslam::Sequence::open(argv[1]);
    mcslam::Settings settings = mcslam::Settings::for_sequence(argv[1], argc > 2 ? argv[2] : "");
    settings.set_sequential(true);  // deterministic: the same poses as `mcslam run --sequential`
    std::cerr << "mcslam " << mcslam::version() << ", vocabulary " << settings.vocabulary() << "\n";
    mcslam::System system(settings);
    int tracked = 0;
    for (std::size_t k = 0; k < sequence.size(); ++k) {
      const auto frame = sequence.load(k, settings.camera().depth_factor);
      const mcslam::FrameReport r =
          system.process(frame.rgb, frame.depth, frame.timestamp, frame.depth_timestamp);
      tracked += r.state == mcslam::State::kOk;
    }
    system.finish();
    for (const mcslam::StampedPose& p : system.trajectory()) {
      const auto& t = p.T_w_c.translation();
      const auto& q = p.T_w_c.quaternion();
      std::printf("%.6f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", p.timestamp, t.x(), t.y(), t.z(),
                  q.x(), q.y(), q.z(), q.w());
    }
    const mcslam::MapSnapshot map = system.map();
    std::cerr << tracked << " of " << sequence.size()
              << " frames tracked; map: " << map.points.size() << " points, " << map.lines.size()
              << " lines, " << map.planes.size() << " planes, " << map.keyframes.size()
              << " keyframes\n";
  } catch (const mcslam::InputError& e) {
    std::cerr << "embed: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
