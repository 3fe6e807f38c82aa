// `mcslam vocabulary SEQUENCES... -o FILE`: a bag-of-words vocabulary from ORB features.
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "command.hpp"
#include "mcslam/app/vocabulary.hpp"

namespace mcslam::cli {
namespace {

class VocabularyCommand : public Command {
 public:
  explicit VocabularyCommand(CLI::App& cli)
      : Command(cli.add_subcommand(
            "vocabulary", "Train a bag-of-words vocabulary from the ORB features of sequences")) {
    CLI::App* cmd = app();
    cmd->add_option("sequences", request_.sequences, "Sequence folders (TUM layout)")->required();
    cmd->add_option("--output,-o", request_.output, "Vocabulary file to write")->required();
    cmd->add_option("--every", request_.every, "Use every N-th image of each sequence (default 5)");
    cmd->add_option("--max-images", request_.max_images,
                    "At most N images per sequence (default 0: all)");
    cmd->add_option("--branching", request_.options.branching,
                    "Children per node, 2-255 (default 10)");
    cmd->add_option("--depth", request_.options.depth, "Levels below the root, 1-16 (default 5)");
    cmd->add_option("--iterations", request_.options.iterations,
                    "k-majority iterations per node (default 10)");
    cmd->add_option("--seed", request_.options.seed, "Seed of the clustering");
    cmd->add_flag("--quiet,-q", quiet_, "No progress and no summary");
  }

  int run(int, char**) override {
    request_.progress = !quiet_ && isatty(fileno(stderr));
    const nlohmann::json summary = app::train_vocabulary(request_);
    if (!quiet_)
      std::cout << "vocabulary: " << summary["words"].get<int>() << " words ("
                << summary["branching"].get<int>() << "^" << summary["depth"].get<int>()
                << " at most), " << summary["nodes"].get<int>() << " nodes, from "
                << summary["descriptors"].get<std::size_t>() << " descriptors of "
                << summary["images"].get<std::size_t>() << " images; "
                << summary["bytes"].get<std::size_t>() << " bytes in " << request_.output << " (id "
                << summary["id"].get<std::string>() << "); extraction "
                << static_cast<int>(summary["extract_seconds"].get<double>()) << " s, training "
                << static_cast<int>(summary["train_seconds"].get<double>()) << " s\n";
    return 0;
  }

 private:
  app::VocabularyRequest request_;
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> make_vocabulary_command(CLI::App& cli) {
  return std::make_unique<VocabularyCommand>(cli);
}

}  // namespace mcslam::cli
