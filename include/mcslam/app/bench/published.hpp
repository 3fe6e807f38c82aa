#pragma once
// Published figures of other systems on the sequences mcslam benchmarks, with their sources, so
// that the bench table can put them beside mcslam's own.

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace mcslam::app::bench {

/// Which of mcslam's figures a published row compares with.
enum class Metric {
  kAteRmse,        ///< metres
  kRpeTransRmse,   ///< metres, RPE over 1 s
  kRpeRotRmseRad,  ///< radians, RPE over 1 s
  kDynamicsTimeS,  ///< seconds per frame spent on finding dynamic objects
};

struct PublishedRow {
  std::string table;   ///< "Table I"
  std::string metric;  ///< as printed, with its unit: "ATE RMSE (m)"
  Metric compares_with = Metric::kAteRmse;
  std::string source;                                  ///< where the figures were read
  std::vector<std::pair<std::string, double>> values;  ///< method, figure
};

/// The short key of a sequence folder name: "rgbd_dataset_freiburg3_walking_xyz" gives
/// "fr3_w_xyz" (the paper's names), "rgbd_bonn_crowd2" gives "bonn_crowd2"; nullopt for a name
/// of neither dataset.
std::optional<std::string> sequence_key(const std::string& folder_name);

/// Published rows for a sequence folder name (empty when there are none).
std::vector<PublishedRow> published_for(const std::string& folder_name);

}  // namespace mcslam::app::bench
