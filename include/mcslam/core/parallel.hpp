#pragma once
// Data-parallel loops over an index range.
//
// The release build hands the work to OpenCV's thread pool (cv::parallel_for_, TBB on Debian),
// which balances the load and honours cv::setNumThreads. ThreadSanitizer cannot see TBB's
// synchronisation, because Debian's libtbb is not instrumented, so it reports every chunk of such
// a loop as racing with the caller and stops there. The ThreadSanitizer build (MCSLAM_TSAN) runs
// the same chunks on std::threads instead: TSan sees their start and join, and so still checks
// what the loop bodies themselves read and write.

#include <functional>

namespace mcslam {

/// Calls body(first, last) on disjoint sub-ranges [first, last) that together cover [begin, end),
/// possibly on several threads at once, and returns when all calls have returned. How the range
/// is split is up to the scheduler, so the body must give the same result for any split and must
/// only write what its own indices own. An exception thrown by a body reaches the caller.
void parallel_for(int begin, int end, const std::function<void(int, int)>& body);

}  // namespace mcslam
