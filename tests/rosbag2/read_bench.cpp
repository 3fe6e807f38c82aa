// Reading speed of recordings: open (which reads and checks the whole recording), then decode
// every frame (load), as `mcslam run` does, without SLAM. Paths are timed interleaved, round
// after round, so that a machine shared with other work slows them alike:
//   recording_read_bench ROUNDS PATH...   (ROS 1 .bag when built with ROS; ROS 2 recordings)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <map>
#include <vector>

#include "mcslam/rosbag2/source.hpp"
#ifdef MCSLAM_HAVE_ROS
#include "mcslam/ros/bag.hpp"
#endif

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: recording_read_bench ROUNDS PATH...\n";
    return 2;
  }
  const int rounds = std::max(1, std::atoi(argv[1]));
  std::map<std::string, std::vector<double>> open_s, total_s;
  std::map<std::string, std::size_t> frames;
  try {
    for (int round = 0; round < rounds; ++round)
      for (int a = 2; a < argc; ++a) {
        const std::string path = argv[a];
        const double t0 = now();
        std::shared_ptr<mcslam::io::FrameSource> source;
        if (mcslam::rosbag2::is_recording_path(path)) {
          source = mcslam::rosbag2::RecordingSource::open(path);
        } else {
#ifdef MCSLAM_HAVE_ROS
          source = mcslam::ros::BagSource::open(path);
#else
          std::cerr << path << ": built without ROS\n";
          return 1;
#endif
        }
        const double t1 = now();
        double checksum = 0.0;
        for (std::size_t i = 0; i < source->frames().size(); ++i) {
          const auto images = source->load(i, 5000.0);
          checksum += images.rgb.at<cv::Vec3b>(0, 0)[0] + images.depth.at<float>(0, 0);
        }
        const double t2 = now();
        open_s[path].push_back(t1 - t0);
        total_s[path].push_back(t2 - t0);
        frames[path] = source->frames().size();
        std::printf(
            "round %d %-40s open+check %.3f s, decode %.3f s, total %.3f s (%zu frames, %g)\n",
            round + 1, path.c_str(), t1 - t0, t2 - t1, t2 - t0, frames[path], checksum);
        std::fflush(stdout);
      }
  } catch (const std::exception& e) {
    std::cerr << "recording_read_bench: " << e.what() << "\n";
    return 1;
  }
  std::printf("median of %d rounds:\n", rounds);
  for (int a = 2; a < argc; ++a) {
    const std::string path = argv[a];
    std::printf("  %-40s open+check %.3f s, total %.3f s, %zu frames\n", path.c_str(),
                median(open_s[path]), median(total_s[path]), frames[path]);
  }
  return 0;
}
