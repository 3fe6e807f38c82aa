#pragma once
// Scheduling priority of the calling thread (Linux: each thread has its own nice value).

namespace mcslam {

/// Adds `increment` (>= 0) to the calling thread's nice value, so that it yields the CPU to the
/// threads that have a deadline when there are more runnable threads than cores. Returns false
/// (and changes nothing) where the system does not allow it; a negative or zero increment is a
/// no-op that returns true.
bool lower_current_thread_priority(int increment);

/// The calling thread's nice value (0 where unknown).
int current_thread_niceness();

}  // namespace mcslam
