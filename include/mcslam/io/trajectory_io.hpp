#pragma once
// TUM trajectory files: one pose per line, "timestamp tx ty tz qx qy qz qw" (T_w_c).

#include <string>

#include "mcslam/core/trajectory.hpp"

namespace mcslam::io {

/// Reads a TUM trajectory. '#' comments and blank lines are ignored; values may be separated by
/// spaces, tabs or commas. Quaternions are normalised. Throws InputError ("<file>:<line>: ...")
/// for a missing file, malformed lines, non-finite values, zero-norm quaternions, timestamps that
/// do not increase strictly, and files without any pose.
Trajectory read_tum_trajectory(const std::string& path);

/// Writes a TUM trajectory atomically (see write_file_atomic) with a
/// "# timestamp tx ty tz qx qy qz qw" header line; timestamps with 6 decimals, the other values
/// with 9 significant digits. A non-empty `note` becomes a first comment line "# <note>".
void write_tum_trajectory(const std::string& path, const Trajectory& trajectory,
                          const std::string& note = {});

}  // namespace mcslam::io
