#include "hmap/maps/column.hpp"

#include <algorithm>
#include <utility>

namespace hmap {

Column::Column(const Column& other) {
  const std::size_t n = other.size();
  if (n == 1) {
    storage_.inline_hvoxel = other[0];
  } else if (n > 1) {
    auto* block = new HVoxel[capacity_for(n)];
    std::copy(other.begin(), other.end(), block);
    storage_.heap = {kHeapTag, static_cast<std::uint32_t>(n), block};
  }
}

Column::Column(Column&& other) noexcept : storage_(other.storage_) { other.storage_.heap = {kEmptyTag, 0, nullptr}; }

Column& Column::operator=(Column other) noexcept {
  std::swap(storage_, other.storage_);
  return *this;
}

Column::~Column() {
  if (on_heap()) delete[] storage_.heap.data;
}

std::size_t Column::heap_bytes() const {
  // The block, and the allocator's own header (16 bytes with glibc).
  return on_heap() ? capacity_for(storage_.heap.size) * sizeof(HVoxel) + 16 : 0;
}

void Column::relocate(std::size_t n) {
  const std::size_t old_size = size();
  const std::size_t keep = std::min(old_size, n);
  const bool was_heap = on_heap();
  HVoxel* old = was_heap ? storage_.heap.data : nullptr;
  if (n >= 2) {
    if (was_heap && capacity_for(n) == capacity_for(old_size)) {
      storage_.heap.size = static_cast<std::uint32_t>(n);
      return;
    }
    auto* block = new HVoxel[capacity_for(n)];
    std::copy(data(), data() + keep, block);
    if (was_heap) delete[] old;
    storage_.heap = {kHeapTag, static_cast<std::uint32_t>(n), block};
    return;
  }
  if (n == 1) {
    const HVoxel first = data()[0];  // called with size >= 1
    if (was_heap) delete[] old;
    storage_.inline_hvoxel = first;
    return;
  }
  if (was_heap) delete[] old;
  storage_.heap = {kEmptyTag, 0, nullptr};
}

void Column::insert(std::size_t pos, const HVoxel& v) {
  const std::size_t n = size();
  if (n == 0) {
    storage_.inline_hvoxel = v;
    return;
  }
  relocate(n + 1);  // n >= 1, so the new size is >= 2: on the heap
  HVoxel* d = storage_.heap.data;
  std::copy_backward(d + pos, d + n, d + n + 1);
  d[pos] = v;
}

void Column::erase(std::size_t first, std::size_t last) {
  const std::size_t n = size();
  HVoxel* d = data();
  std::copy(d + last, d + n, d + first);
  relocate(n - (last - first));
}

void Column::clear() { relocate(0); }

void Column::merge(const HVoxel& v, float gap, const MapParams& params) {
  // Sorted and disjoint: the HVoxels within `gap` of v form one contiguous run.
  const std::size_t n = size();
  const std::size_t first = lower_bound(v.z_min - gap);
  std::size_t last = first;
  HVoxel united = v;
  const HVoxel* d = data();
  while (last < n && d[last].z_min <= v.z_max + gap) {
    united.z_min = std::min(united.z_min, d[last].z_min);
    united.z_max = std::max(united.z_max, d[last].z_max);
    united.count += d[last].count;
    ++last;
  }
  update_density(united, params);
  if (first == last) {
    insert(first, united);
    return;
  }
  data()[first] = united;
  if (last > first + 1) erase(first + 1, last);
}

bool Column::is_valid() const {
  const HVoxel* d = data();
  const std::size_t n = size();
  for (std::size_t i = 0; i < n; ++i) {
    if (!(d[i].z_min <= d[i].z_max)) return false;
    if (i > 0 && !(d[i - 1].z_max < d[i].z_min)) return false;
  }
  return true;
}

}  // namespace hmap
