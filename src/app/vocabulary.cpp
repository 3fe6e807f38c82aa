#include "mcslam/app/vocabulary.hpp"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "mcslam/core/error.hpp"
#include "mcslam/io/sequence.hpp"

namespace mcslam::app {

namespace {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

nlohmann::json train_vocabulary(const VocabularyRequest& request) {
  if (request.sequences.empty()) throw InputError("vocabulary: give at least one sequence folder");
  if (request.every < 1) throw InputError("vocabulary: --every must be >= 1");
  if (request.max_images < 0) throw InputError("vocabulary: --max-images must be >= 0");
  if (request.output.empty()) throw InputError("vocabulary: --output is required");
  if (auto problem = request.options.check()) throw InputError("vocabulary: " + *problem);
  // Before minutes of extraction and training: the output's folder must exist.
  const std::filesystem::path parent = std::filesystem::path(request.output).parent_path();
  if (!parent.empty() && !std::filesystem::is_directory(parent))
    throw InputError(file_error(request.output, "cannot write (its folder does not exist)"));
  const features::OrbExtractor extractor(request.orb);

  const auto start = std::chrono::steady_clock::now();
  std::vector<std::vector<features::OrbDescriptor>> images;
  nlohmann::json sources = nlohmann::json::array();
  std::size_t descriptors = 0;
  for (const std::string& dir : request.sequences) {
    const io::RgbdSequence sequence = io::RgbdSequence::open(dir);
    int used = 0;
    const auto& frames = sequence.frames();
    for (std::size_t i = 0; i < frames.size(); i += static_cast<std::size_t>(request.every)) {
      if (request.max_images > 0 && used >= request.max_images) break;
      const cv::Mat gray = cv::imread(frames[i].rgb_path, cv::IMREAD_GRAYSCALE);
      if (gray.empty())
        throw InputError(
            file_error(frames[i].rgb_path, "cannot read the image (missing or corrupt)"));
      auto features = extractor.extract(gray);
      descriptors += features.descriptors.size();
      images.push_back(std::move(features.descriptors));
      ++used;
    }
    sources.push_back({{"sequence", dir}, {"images", used}});
    if (request.progress) std::cerr << "vocabulary: " << dir << ": " << used << " images\n";
  }
  const double extract_s = seconds_since(start);
  const auto train_start = std::chrono::steady_clock::now();
  const place::Vocabulary voc = place::Vocabulary::train(images, request.options);
  const double train_s = seconds_since(train_start);
  voc.save(request.output);

  char id[17];
  std::snprintf(id, sizeof(id), "%016llx", static_cast<unsigned long long>(voc.id()));
  return {{"output", request.output},
          {"sequences", sources},
          {"images", images.size()},
          {"descriptors", descriptors},
          {"branching", voc.branching()},
          {"depth", voc.depth()},
          {"words", voc.words()},
          {"nodes", voc.nodes()},
          {"bytes", std::filesystem::file_size(request.output)},
          {"id", id},
          {"extract_seconds", extract_s},
          {"train_seconds", train_s}};
}

}  // namespace mcslam::app
