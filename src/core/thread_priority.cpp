#include "mcslam/core/thread_priority.hpp"

#if defined(__linux__)
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#endif

namespace mcslam {

#if defined(__linux__)
namespace {
id_t thread_id() { return static_cast<id_t>(::syscall(SYS_gettid)); }
}  // namespace

int current_thread_niceness() {
  errno = 0;
  const int nice = ::getpriority(PRIO_PROCESS, thread_id());
  return errno == 0 ? nice : 0;
}

bool lower_current_thread_priority(int increment) {
  if (increment <= 0) return true;
  // On Linux PRIO_PROCESS with a thread id sets that thread's nice value alone.
  return ::setpriority(PRIO_PROCESS, thread_id(), current_thread_niceness() + increment) == 0;
}
#else
int current_thread_niceness() { return 0; }
bool lower_current_thread_priority(int increment) { return increment <= 0; }
#endif

}  // namespace mcslam
