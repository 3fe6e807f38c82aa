// The control for facade_lean_test.cpp: the pipeline's own header does pull in Ceres and glog,
// so the checks there detect them.
#include <gtest/gtest.h>

#include "mcslam/slam/system.hpp"

#if !defined(CERES_EXPORT) || !defined(CHECK_EQ)
#error "the check of facade_lean_test.cpp would not detect Ceres or glog"
#endif

TEST(FacadeLean, PipelineHeaderPullsInCeres) { SUCCEED(); }
