#pragma once
// The binary test pattern of the ORB descriptor (internal to the features module).

#include <array>

namespace mcslam::features::detail {

/// One binary test: compares the (smoothed) intensities at (x1, y1) and (x2, y2), offsets from
/// the keypoint in the keypoint's rotated frame. Every point lies within radius 15.
struct TestPair {
  int x1 = 0;
  int y1 = 0;
  int x2 = 0;
  int y2 = 0;
};

/// The 256 tests, generated once per process (about 0.1 s) by a fixed, platform-independent
/// procedure: 4096 candidate pairs of points drawn uniformly in the patch disc from a
/// fixed-seed std::mt19937_64, then a greedy selection (as for rBRIEF) of tests with a balanced
/// outcome and low mutual correlation, measured on orientation-normalised corner patches of a
/// synthetic "dead leaves" texture. Only integer and correctly rounded floating-point
/// operations are involved, so every platform gets the same tests.
const std::array<TestPair, 256>& orb_test_pattern();

/// Half-width of the circular patch of radius kHalfPatch (15) at row offset |v| in [0, 15]:
/// the largest u with u^2 + v^2 <= 15^2 + 15 (a digital disk of radius ~15.5).
std::array<int, 16> circle_half_widths();

}  // namespace mcslam::features::detail
