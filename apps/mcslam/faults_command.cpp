// `mcslam faults SEQUENCE -o OUT --fault ...`: a copy of a sequence with faults injected.
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "command.hpp"
#include "mcslam/app/faults.hpp"

namespace mcslam::cli {
namespace {

class FaultsCommand : public Command {
 public:
  explicit FaultsCommand(CLI::App& cli)
      : Command(cli.add_subcommand(
            "faults",
            "Write a copy of a sequence with faults injected (dropped, black, frozen frames...)")) {
    app()->add_option("sequence", request_.sequence_dir, "Sequence folder")->required();
    app()->add_option("--output,-o", request_.output_dir, "Folder for the faulty copy")->required();
    app()->add_option("--fault", fault_texts_,
                      "drop-every:K, drop-burst:START:LEN, black:START:LEN, saturate:START:LEN, "
                      "zero-depth:START:LEN, freeze:START:LEN, time-jump:START:SECONDS, "
                      "kidnap:START:LEN (frames are 0-based; repeat for several; none: a "
                      "plain copy)");
    app()->add_flag("--quiet,-q", quiet_, "No summary");
  }

  int run(int, char**) override {
    for (const auto& t : fault_texts_) request_.faults.push_back(app::parse_fault(t));
    const nlohmann::json report = app::write_faulty_sequence(request_);
    if (!quiet_)
      std::cout << "wrote " << report["frames_out"].get<int>() << " of "
                << report["frames_in"].get<int>() << " frames to " << request_.output_dir
                << " (faults.json lists the faults)\n";
    return 0;
  }

 private:
  app::FaultRequest request_;
  std::vector<std::string> fault_texts_;
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> make_faults_command(CLI::App& cli) {
  return std::make_unique<FaultsCommand>(cli);
}

}  // namespace mcslam::cli
