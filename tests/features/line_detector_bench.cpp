// Line detectors side by side on a real sequence: the time of one detection at the line
// extractor's scale on one thread, the segments found, and how many of OpenCV's LSD segments
// each finds again (both endpoints within half a pixel). Not a test: a benchmark that prints a
// table (docs/crowd.md, "A line detector of our own").
//
//   ./build/tests/line_detector_bench SEQ_DIR [FRAMES] [ROUNDS]
//
// SEQ_DIR is a TUM-layout sequence (rgb.txt); every 3rd of its first 3 x FRAMES images (100 by
// default) is scaled by lines.detection_scale (0.4) as the extractor does; each detector runs
// over all of them ROUNDS times (3), rounds interleaved, and the median round is reported.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc/fast_line_detector.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "mcslam/features/lines.hpp"
#include "region_line_detector.hpp"

namespace {

using Segments = std::vector<cv::Vec4f>;
using Detect = std::function<void(const cv::Mat&, Segments&)>;

double length(const cv::Vec4f& s) { return std::hypot(s[2] - s[0], s[3] - s[1]); }

bool same(const cv::Vec4f& a, const cv::Vec4f& b) {
  return std::hypot(a[0] - b[0], a[1] - b[1]) < 0.5 && std::hypot(a[2] - b[2], a[3] - b[3]) < 0.5;
}

std::vector<cv::Mat> load(const std::string& dir, int frames, double scale) {
  std::ifstream list(dir + "/rgb.txt");
  std::vector<cv::Mat> images;
  std::string line;
  for (int k = 0; std::getline(list, line) && static_cast<int>(images.size()) < frames;) {
    if (line.empty() || line[0] == '#') continue;
    if (k++ % 3 != 0) continue;
    std::istringstream fields(line);
    std::string stamp, file;
    fields >> stamp >> file;
    const cv::Mat gray = cv::imread(dir + "/" + file, cv::IMREAD_GRAYSCALE);
    if (gray.empty()) {
      std::fprintf(stderr, "line_detector_bench: %s/%s: cannot read the image\n", dir.c_str(),
                   file.c_str());
      return {};
    }
    cv::Mat scaled;
    cv::resize(gray, scaled, cv::Size(), scale, scale, cv::INTER_AREA);
    images.push_back(scaled);
  }
  return images;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: line_detector_bench SEQ_DIR [FRAMES] [ROUNDS]\n");
    return 2;
  }
  const int frames = argc > 2 ? std::max(1, std::atoi(argv[2])) : 100;
  const int rounds = argc > 3 ? std::max(1, std::atoi(argv[3])) : 3;
  cv::setNumThreads(1);
  const std::vector<cv::Mat> images =
      load(argv[1], frames, mcslam::features::LineOptions{}.detection_scale);
  if (images.empty()) {
    std::fprintf(stderr, "line_detector_bench: %s: no images (a TUM-layout sequence?)\n", argv[1]);
    return 1;
  }

  const cv::Ptr<cv::LineSegmentDetector> lsd =
      cv::createLineSegmentDetector(cv::LSD_REFINE_STD, 1.0);
  const cv::Ptr<cv::ximgproc::FastLineDetector> fld =
      cv::ximgproc::createFastLineDetector(10, 1.414213562f, 50.0, 50.0, 3, false);
  mcslam::features::detail::RegionLineDetector region;
  const std::vector<std::pair<const char*, Detect>> detectors{
      {"lsd (OpenCV)", [&](const cv::Mat& image, Segments& out) { lsd->detect(image, out); }},
      {"region", [&](const cv::Mat& image, Segments& out) { region.detect(image, out); }},
      {"fld (OpenCV contrib)",
       [&](const cv::Mat& image, Segments& out) { fld->detect(image, out); }},
  };

  // The reference segments, and each detector's output, once.
  std::vector<Segments> reference(images.size());
  for (std::size_t i = 0; i < images.size(); ++i) lsd->detect(images[i], reference[i]);
  std::vector<std::vector<double>> round_ms(detectors.size());
  for (int r = 0; r < rounds; ++r) {
    for (std::size_t d = 0; d < detectors.size(); ++d) {
      Segments out;
      const auto start = std::chrono::steady_clock::now();
      for (const cv::Mat& image : images) detectors[d].second(image, out);
      const std::chrono::duration<double, std::milli> spent =
          std::chrono::steady_clock::now() - start;
      round_ms[d].push_back(spent.count() / static_cast<double>(images.size()));
    }
  }

  std::printf("%zu images of %dx%d, %d rounds; segments of 10 px or more\n\n", images.size(),
              images[0].cols, images[0].rows, rounds);
  std::printf("| detector | ms per image (median round) | vs lsd | segments | lsd's found |\n");
  std::printf("|---|---|---|---|---|\n");
  double lsd_ms = 0.0;
  for (std::size_t d = 0; d < detectors.size(); ++d) {
    std::vector<double> ms = round_ms[d];
    std::nth_element(ms.begin(), ms.begin() + static_cast<long>(ms.size() / 2), ms.end());
    const double median = ms[ms.size() / 2];
    if (d == 0) lsd_ms = median;
    long segments = 0, reference_long = 0, found = 0;
    for (std::size_t i = 0; i < images.size(); ++i) {
      Segments out;
      detectors[d].second(images[i], out);
      for (const cv::Vec4f& s : out) segments += length(s) >= 10.0 ? 1 : 0;
      for (const cv::Vec4f& e : reference[i]) {
        if (length(e) < 10.0) continue;
        ++reference_long;
        found += std::any_of(out.begin(), out.end(), [&](const cv::Vec4f& s) { return same(e, s); })
                     ? 1
                     : 0;
      }
    }
    std::printf("| %s | %.2f | %.2fx | %ld | %.3f |\n", detectors[d].first, median, median / lsd_ms,
                segments,
                static_cast<double>(found) / static_cast<double>(std::max(1L, reference_long)));
  }
  return 0;
}
