#include "mcslam/io/trajectory_io.hpp"

#include <cmath>
#include <string_view>

#include "io/text_util.hpp"
#include "mcslam/core/error.hpp"
#include "mcslam/io/files.hpp"

namespace mcslam::io {

Trajectory read_tum_trajectory(const std::string& path) {
  const std::vector<std::string> lines = detail::split_lines(detail::read_text_file(path));
  static constexpr const char* kNames[8] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};

  Trajectory trajectory;
  std::string previous_token;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::string& line = lines[i];
    if (detail::is_blank_or_comment(line)) continue;
    const std::string where = detail::at_line(path, static_cast<int>(i + 1));
    const auto fields = detail::split_fields(line, /*commas=*/true);
    if (fields.size() != 8)
      throw InputError(
          file_error(where, "expected 8 values 'timestamp tx ty tz qx qy qz qw', got " +
                                std::to_string(fields.size())));
    double v[8];
    for (int k = 0; k < 8; ++k) {
      const auto parsed = detail::parse_double(fields[k]);
      if (!parsed)
        throw InputError(file_error(
            where, std::string("malformed ") + kNames[k] + " '" + std::string(fields[k]) + "'"));
      if (!std::isfinite(*parsed))
        throw InputError(file_error(
            where, std::string("non-finite ") + kNames[k] + " '" + std::string(fields[k]) + "'"));
      v[k] = *parsed;
    }
    const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    const double norm = q.norm();
    if (!(norm > 1e-12) || !std::isfinite(norm))
      throw InputError(file_error(where, "quaternion has zero norm"));
    if (!trajectory.empty() && !(v[0] > trajectory.back().timestamp))
      throw InputError(
          file_error(where, "timestamps must increase strictly: " + std::string(fields[0]) +
                                " follows " + previous_token));
    previous_token = std::string(fields[0]);
    StampedPose pose;
    pose.timestamp = v[0];
    pose.T_w_c = SE3(Eigen::Quaterniond(q.coeffs() / norm), Eigen::Vector3d(v[1], v[2], v[3]));
    trajectory.push_back(pose);
  }
  if (trajectory.empty()) throw InputError(file_error(path, "no poses in the file"));
  return trajectory;
}

void write_tum_trajectory(const std::string& path, const Trajectory& trajectory,
                          const std::string& note) {
  std::string out = note.empty() ? std::string() : "# " + note + "\n";
  out += "# timestamp tx ty tz qx qy qz qw\n";
  out.reserve(out.size() + trajectory.size() * 128);
  for (const StampedPose& pose : trajectory) {
    const Eigen::Vector3d& t = pose.T_w_c.translation();
    const Eigen::Quaterniond& q = pose.T_w_c.quaternion();
    out += detail::format_double("%.6f", pose.timestamp);
    for (double value : {t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()}) {
      out += ' ';
      out += detail::format_double("%.9g", value);
    }
    out += '\n';
  }
  write_file_atomic(path, out);
}

}  // namespace mcslam::io
