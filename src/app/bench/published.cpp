#include "mcslam/app/bench/published.hpp"

#include <algorithm>
#include <map>
#include <regex>

namespace mcslam::app::bench {
namespace {

const char* const kPaper =
    "\"Semantic SLAM Fusing Moving Constraint for Dynamic Objects under Indoor Environments\" "
    "(the paper mcslam implements, ../shared/docs/paper.md)";

using Values = std::vector<std::pair<std::string, double>>;

Values paper_methods(double orb, double ds, double dyna, double planar, double manhattan,
                     double proposed) {
  return {{"ORB-SLAM2", orb},
          {"DS-SLAM", ds},
          {"Dyna-SLAM", dyna},
          {"Planar-SLAM", planar},
          {"Manhattan-SLAM", manhattan},
          {"paper's system", proposed}};
}

/// Tables I-IV of the paper, by the paper's sequence names.
std::map<std::string, std::vector<PublishedRow>> paper_tables() {
  struct Line {
    const char* key;
    double v[6];
  };
  const Line ate[] = {
      {"fr2_desk_w_person", {0.0532, 0.0063, 0.0061, 0.0811, 0.0191, 0.0056}},
      {"fr3_s_static", {0.0119, 0.0071, 0.0071, 0.0237, 0.0084, 0.0068}},
      {"fr3_s_xyz", {0.0134, 0.0119, 0.0151, 0.0197, 0.0102, 0.0118}},
      {"fr3_s_half", {0.0193, 0.0147, 0.0168, 0.0502, 0.0658, 0.0155}},
      {"fr3_s_rpy", {0.0301, 0.0228, 0.0199, 0.0715, 0.0286, 0.0258}},
      {"fr3_w_static", {0.2513, 0.0077, 0.0079, 0.3053, 0.3027, 0.0075}},
      {"fr3_w_xyz", {0.4032, 0.1702, 0.0180, 0.2050, 1.0429, 0.0179}},
      {"fr3_w_half", {0.3508, 0.0351, 0.0333, 0.6156, 0.6692, 0.0329}},
      {"fr3_w_rpy", {0.7631, 0.4488, 0.0261, 0.4494, 0.8907, 0.1945}},
  };
  const Line rpe_t[] = {
      {"fr2_desk_w_person", {0.0104, 0.0032, 0.0112, 0.0250, 0.0046, 0.0032}},
      {"fr3_s_static", {0.0097, 0.0044, 0.0124, 0.0093, 0.0051, 0.0051}},
      {"fr3_s_xyz", {0.0153, 0.0085, 0.0201, 0.0114, 0.0079, 0.0075}},
      {"fr3_s_half", {0.0210, 0.0105, 0.0245, 0.0397, 0.0107, 0.0103}},
      {"fr3_s_rpy", {0.0141, 0.0139, 0.0132, 0.0199, 0.0128, 0.0173}},
      {"fr3_w_static", {0.0249, 0.0049, 0.0103, 0.0184, 0.0133, 0.0064}},
      {"fr3_w_xyz", {0.0293, 0.0134, 0.0214, 0.0327, 0.0238, 0.0124}},
      {"fr3_w_half", {0.0276, 0.0151, 0.0259, 0.0765, 0.0557, 0.0135}},
      {"fr3_w_rpy", {0.0642, 0.0209, 0.0315, 0.0562, 0.0317, 0.0211}},
  };
  const Line rpe_r[] = {
      {"fr2_desk_w_person", {0.0078, 0.0071, 0.0081, 0.0098, 0.0073, 0.0072}},
      {"fr3_s_static", {0.0097, 0.0037, 0.0065, 0.0063, 0.0041, 0.0036}},
      {"fr3_s_xyz", {0.0079, 0.0078, 0.0083, 0.0091, 0.0077, 0.0080}},
      {"fr3_s_half", {0.0091, 0.0095, 0.0074, 0.0173, 0.0115, 0.0090}},
      {"fr3_s_rpy", {0.0120, 0.0106, 0.0105, 0.0142, 0.0102, 0.0100}},
      {"fr3_w_static", {0.0165, 0.0041, 0.0032, 0.0101, 0.0074, 0.0045}},
      {"fr3_w_xyz", {0.0335, 0.0102, 0.0331, 0.0169, 0.0145, 0.0096}},
      {"fr3_w_half", {0.0423, 0.0109, 0.0102, 0.0442, 0.0402, 0.0097}},
      {"fr3_w_rpy", {0.0964, 0.0123, 0.0092, 0.0632, 0.0176, 0.0129}},
  };
  struct TimeLine {
    const char* key;
    double ds, proposed, proposed_points;
  };
  const TimeLine times[] = {
      {"fr3_w_static", 0.0813, 0.0999, 0.0521},
      {"fr3_w_xyz", 0.0871, 0.1060, 0.0577},
      {"fr3_w_half", 0.0842, 0.1166, 0.0535},
      {"fr3_w_rpy", 0.0854, 0.0827, 0.0565},
  };
  const std::string source = std::string(kPaper);
  std::map<std::string, std::vector<PublishedRow>> rows;
  for (const Line& l : ate)
    rows[l.key].push_back({"Table I", "ATE RMSE (m)", Metric::kAteRmse, source + ", Table I",
                           paper_methods(l.v[0], l.v[1], l.v[2], l.v[3], l.v[4], l.v[5])});
  for (const Line& l : rpe_t)
    rows[l.key].push_back({"Table II", "RPE translation RMSE (m)", Metric::kRpeTransRmse,
                           source + ", Table II",
                           paper_methods(l.v[0], l.v[1], l.v[2], l.v[3], l.v[4], l.v[5])});
  for (const Line& l : rpe_r)
    rows[l.key].push_back({"Table III", "RPE rotation RMSE (rad)", Metric::kRpeRotRmseRad,
                           source + ", Table III",
                           paper_methods(l.v[0], l.v[1], l.v[2], l.v[3], l.v[4], l.v[5])});
  for (const TimeLine& l : times)
    rows[l.key].push_back({"Table IV",
                           "time to detect dynamic objects per frame (s)",
                           Metric::kDynamicsTimeS,
                           source + ", Table IV (Intel i7-10700, 16 threads)",
                           {{"DS-SLAM", l.ds},
                            {"paper's system", l.proposed},
                            {"paper's system, points only", l.proposed_points}}});
  return rows;
}

/// Bonn RGB-D Dynamic: ReFusion and DynaSLAM (N+G) as published in the ReFusion paper, and
/// ORB-SLAM2 as run by the DDN-SLAM authors; read in WildGS-SLAM, which reprints them.
std::map<std::string, std::vector<PublishedRow>> bonn_tables() {
  struct Line {
    const char* key;
    double refusion, dyna, orb;
  };
  const Line lines[] = {
      {"bonn_balloon", 0.175, 0.030, 0.065},
      {"bonn_balloon2", 0.254, 0.029, 0.230},
      {"bonn_crowd", 0.204, 0.016, 0.049},
      {"bonn_crowd2", 0.155, 0.031, 0.098},
      {"bonn_moving_nonobstructing_box", 0.071, 0.232, 0.032},
      {"bonn_moving_nonobstructing_box2", 0.179, 0.039, 0.039},
      {"bonn_person_tracking", 0.289, 0.061, 0.069},
      {"bonn_person_tracking2", 0.463, 0.078, 0.079},
  };
  const std::string source =
      "ReFusion and DynaSLAM (N+G): Palazzolo et al., \"ReFusion\", IROS 2019; ORB-SLAM2: as run "
      "in the DDN-SLAM paper; all read in WildGS-SLAM (arXiv 2504.03886), Table 3, which "
      "reprints them (cm there)";
  std::map<std::string, std::vector<PublishedRow>> rows;
  for (const Line& l : lines)
    rows[l.key].push_back(
        {"Bonn ATE",
         "ATE RMSE (m)",
         Metric::kAteRmse,
         source,
         {{"ReFusion", l.refusion}, {"DynaSLAM (N+G)", l.dyna}, {"ORB-SLAM2", l.orb}}});
  // NGD-SLAM's own figures on the crowd sequences (arXiv 2405.07392v5, Table II).
  const std::pair<const char*, double> ngd[] = {
      {"bonn_crowd", 0.024}, {"bonn_crowd2", 0.025}, {"bonn_crowd3", 0.033}};
  for (const auto& [key, value] : ngd)
    rows[key].push_back({"NGD-SLAM Table II",
                         "ATE RMSE (m)",
                         Metric::kAteRmse,
                         "NGD-SLAM (arXiv 2405.07392v5), Table II, read from a transcription",
                         {{"NGD-SLAM", value}}});
  return rows;
}

/// Figures measured on mcslam's development machine and given in the developers' brief.
std::map<std::string, std::vector<PublishedRow>> brief_figures() {
  std::map<std::string, std::vector<PublishedRow>> rows;
  rows["fr1_rpy"].push_back({"brief",
                             "ATE RMSE (m)",
                             Metric::kAteRmse,
                             "ORB-SLAM2 run on mcslam's 2-core development machine, as given in "
                             "the project brief (not a published figure)",
                             {{"ORB-SLAM2 (this machine)", 0.0217}}});
  return rows;
}

}  // namespace

std::optional<std::string> sequence_key(const std::string& folder_name) {
  std::string name = folder_name;
  std::transform(name.begin(), name.end(), name.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  std::smatch m;
  static const std::regex bonn(R"((?:^|_)bonn_(.+)$)");
  if (std::regex_search(name, m, bonn)) return "bonn_" + m[1].str();
  static const std::regex tum(R"(freiburg([123])_(.+)$)");
  if (!std::regex_search(name, m, tum)) return std::nullopt;
  std::string rest = m[2].str();
  const std::pair<const char*, const char*> words[] = {
      {"walking_", "w_"}, {"sitting_", "s_"}, {"halfsphere", "half"}, {"_with_", "_w_"}};
  for (const auto& [from, to] : words)
    if (const auto at = rest.find(from); at != std::string::npos)
      rest.replace(at, std::string(from).size(), to);
  return "fr" + m[1].str() + "_" + rest;
}

std::vector<PublishedRow> published_for(const std::string& folder_name) {
  const auto key = sequence_key(folder_name);
  if (!key) return {};
  static const auto paper = paper_tables();
  static const auto bonn = bonn_tables();
  static const auto brief = brief_figures();
  std::vector<PublishedRow> rows;
  for (const auto* table : {&paper, &bonn, &brief})
    if (const auto it = table->find(*key); it != table->end())
      rows.insert(rows.end(), it->second.begin(), it->second.end());
  return rows;
}

}  // namespace mcslam::app::bench
