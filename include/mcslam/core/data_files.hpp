#pragma once
// The data files mcslam reads at run time (the default ORB vocabulary): installed in
// <prefix>/share/mcslam, copied to <build>/share/mcslam in the build tree. Never looked up in the
// source tree, so that an installed or moved mcslam works on its own.

#include <string>
#include <vector>

namespace mcslam {

/// Where data file `name` is looked for, in order:
///   1. $MCSLAM_DATA_DIR/<name>
///   2. the folder set with set_data_dir_hint() (the installed CMake and pkg-config packages
///      set it in programs that include mcslam/mcslam.hpp)
///   3. share/mcslam/<name> in the folders above the binary that holds this code (an
///      executable, or a Python extension module), then above the running executable:
///      <prefix>/bin/mcslam finds <prefix>/share/mcslam, build/tests/x finds build/share/mcslam
///   4. the installation folder chosen when mcslam was configured (CMAKE_INSTALL_PREFIX)
std::vector<std::string> data_file_candidates(const std::string& name);

/// The first existing file of data_file_candidates(name); when none exists, the first candidate
/// (so that the error reading it names a path and MCSLAM_DATA_DIR tells how to fix it).
std::string find_data_file(const std::string& name);

/// A folder to look in before the binary's own (see data_file_candidates); "" clears it.
void set_data_dir_hint(const std::string& directory);

}  // namespace mcslam
