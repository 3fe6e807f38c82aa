#pragma once
// Helpers of the io tests: temporary directories and InputError message checks.

#include "support/temp_dir.hpp"

namespace mcslam::io::iotest {

using TempDir = mcslam::test::TempDir;
using mcslam::test::expect_input_error;

}  // namespace mcslam::io::iotest
