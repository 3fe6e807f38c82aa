// mcslam/mcslam.hpp is lean: it pulls in neither Ceres nor glog (through the tracker and the
// optimiser's headers). internal_headers_test.cpp shows that these checks can fail.
#include <gtest/gtest.h>

#include "mcslam/mcslam.hpp"

#if defined(CERES_EXPORT) || defined(CERES_VERSION_MAJOR)
#error "mcslam/mcslam.hpp includes Ceres"
#endif
#if defined(CHECK_EQ) || defined(GOOGLE_LOG_INFO)
#error "mcslam/mcslam.hpp includes glog"
#endif

TEST(FacadeLean, VersionHeaderMatchesTheLibrary) {
  EXPECT_EQ(mcslam::version(), MCSLAM_VERSION_STRING);
  EXPECT_EQ(std::string(MCSLAM_VERSION_STRING), std::to_string(MCSLAM_VERSION_MAJOR) + "." +
                                                    std::to_string(MCSLAM_VERSION_MINOR) + "." +
                                                    std::to_string(MCSLAM_VERSION_PATCH));
}
