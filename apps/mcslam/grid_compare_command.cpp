// `mcslam grid-compare REF FULL`: cells occupied in one run's grid where another's saw free
// (docs/occupancy.md).
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "command.hpp"
#include "mcslam/mapping/grid_change.hpp"

namespace mcslam::cli {
namespace {

class GridCompareCommand : public Command {
 public:
  explicit GridCompareCommand(CLI::App& cli)
      : Command(cli.add_subcommand(
            "grid-compare",
            "Cells occupied in one run's grid (FULL) where another's (REF) saw free: people left "
            "in the map")) {
    app()->add_option("REF", ref_dir_, "Output folder of the reference run")->required();
    app()->add_option("FULL", full_dir_, "Output folder of the run to check")->required();
    app()->add_flag("--json", json_, "Print JSON");
  }

  int run(int, char**) override {
    const mapping::OccupancyGrid ref = mapping::read_run_grid(ref_dir_);
    const mapping::OccupancyGrid full = mapping::read_run_grid(full_dir_);
    const mapping::GridChange c = mapping::compare_grids(ref, full);
    if (json_) {
      std::cout << nlohmann::json{{"full_occupied_seen_by_ref", c.full_occupied_seen},
                                  {"appeared", c.appeared},
                                  {"appeared_rate", c.appeared_rate},
                                  {"ref_occupied_seen_by_full", c.ref_occupied_seen},
                                  {"vanished", c.vanished}}
                       .dump(2)
                << "\n";
      return 0;
    }
    std::cout << std::fixed << std::setprecision(2)
              << "occupied in FULL where REF saw free: " << c.appeared << " of "
              << c.full_occupied_seen << " cells REF saw (" << 100.0 * c.appeared_rate << " %)\n"
              << "free in FULL where REF had occupied: " << c.vanished << " of "
              << c.ref_occupied_seen << " cells FULL saw\n";
    return 0;
  }

 private:
  std::string ref_dir_, full_dir_;
  bool json_ = false;
};

}  // namespace

std::unique_ptr<Command> make_grid_compare_command(CLI::App& cli) {
  return std::make_unique<GridCompareCommand>(cli);
}

}  // namespace mcslam::cli
