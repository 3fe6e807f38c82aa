#include "mcslam/core/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <opencv2/core/utility.hpp>
#include <thread>
#include <vector>

namespace mcslam {

namespace {

#ifdef MCSLAM_TSAN
// Workers take the next `grain` indices from a shared counter until none are left, so uneven
// sub-ranges (image pyramid levels) still balance. At least two workers, so that the build meant
// to find races runs the bodies concurrently even where OpenCV is told to use one thread.
void run_on_std_threads(int begin, int end, const std::function<void(int, int)>& body) {
  const int workers = std::min(end - begin, std::max(2, cv::getNumThreads()));
  const int grain = std::max(1, (end - begin) / (4 * workers));
  std::atomic<int> next{begin};
  std::exception_ptr first_error;
  std::mutex error_mutex;
  const auto work = [&] {
    for (int first = next.fetch_add(grain); first < end; first = next.fetch_add(grain)) {
      try {
        body(first, std::min(end, first + grain));
      } catch (...) {
        const std::lock_guard<std::mutex> lock(error_mutex);
        if (!first_error) first_error = std::current_exception();
      }
    }
  };
  std::vector<std::thread> threads;
  threads.reserve(static_cast<std::size_t>(workers - 1));
  for (int t = 1; t < workers; ++t) threads.emplace_back(work);
  work();
  for (std::thread& thread : threads) thread.join();
  if (first_error) std::rethrow_exception(first_error);
}
#endif

}  // namespace

void parallel_for(int begin, int end, const std::function<void(int, int)>& body) {
  if (end <= begin) return;
#ifdef MCSLAM_TSAN
  run_on_std_threads(begin, end, body);
#else
  cv::parallel_for_(cv::Range(begin, end),
                    [&](const cv::Range& range) { body(range.start, range.end); });
#endif
}

}  // namespace mcslam
