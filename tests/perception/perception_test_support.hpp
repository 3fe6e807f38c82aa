#pragma once
// Helpers of the perception tests: temporary directories and InputError message checks.

#include "support/temp_dir.hpp"

namespace mcslam::perception::test {

/// Temporary directories named after the perception tests.
class TempDir : public mcslam::test::TempDir {
 public:
  TempDir() : mcslam::test::TempDir("mcslam_perception_test") {}
};
using mcslam::test::expect_input_error;

}  // namespace mcslam::perception::test
