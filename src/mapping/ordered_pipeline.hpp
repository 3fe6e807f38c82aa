#pragma once
// Work on items 0..n-1 gathered in parallel and applied in order.

#include <cstddef>
#include <functional>

namespace mcslam::mapping::detail {

/// Calls gather(k, slot) for every item k in [0, n), on this thread and on `helpers` others,
/// and apply(k, slot) on this thread for k = 0, 1, ... in order, each after gather(k, slot)
/// returned. There are helpers + 1 slots; item k uses slot k % (helpers + 1), so a slot is
/// gathered into again only once the item before in it was applied: the slots can hold each
/// item's scratch space. This thread gathers too whenever the next item to apply is not being
/// gathered yet. The first exception of gather or apply stops the work (no new item is started)
/// and is rethrown here once every helper has returned. Without a thread to be had, this thread
/// does all of it.
void gather_and_apply_in_order(std::size_t n, std::size_t helpers,
                               const std::function<void(std::size_t, std::size_t)>& gather,
                               const std::function<void(std::size_t, std::size_t)>& apply);

}  // namespace mcslam::mapping::detail
