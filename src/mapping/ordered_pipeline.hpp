#pragma once
// Work on items 0..n-1 gathered in parallel and applied in order.

#include <cstddef>
#include <functional>

namespace mcslam::mapping::detail {

/// Calls gather(k, slot) for every item k in [0, n), on this thread and on `helpers` others,
/// and apply(k, slot) on this thread for k = 0, 1, ... in order, each after gather(k, slot)
/// returned. There are `slots` slots (at least helpers + 1; fewer count as that many); item k
/// uses slot k % slots, so a slot is gathered into again only once the item before in it was
/// applied: the slots can hold each item's scratch space. Slots beyond helpers + 1 let the
/// helpers gather ahead while this thread applies. This thread gathers too whenever the next
/// item to apply is not being gathered yet. The first exception of gather or apply stops the
/// work (no new item is started) and is rethrown here once every helper has returned. Without a
/// thread to be had, this thread does all of it.
void gather_and_apply_in_order(std::size_t n, std::size_t helpers, std::size_t slots,
                               const std::function<void(std::size_t, std::size_t)>& gather,
                               const std::function<void(std::size_t, std::size_t)>& apply);

/// The slots gather_and_apply_in_order() uses for `slots` and `helpers`.
inline std::size_t pipeline_slots(std::size_t helpers, std::size_t slots) {
  return slots > helpers + 1 ? slots : helpers + 1;
}

}  // namespace mcslam::mapping::detail
