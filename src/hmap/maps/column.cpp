#include "hmap/maps/column.hpp"

#include <algorithm>
#include <cstring>
#include <utility>

namespace hmap {

Column::Column(const Column& other) {
  if (other.size_ > 1) grow(other.size_);
  std::copy(other.begin(), other.end(), data());
  size_ = other.size_;
}

Column::Column(Column&& other) noexcept
    : size_(other.size_), capacity_(other.capacity_), storage_(other.storage_) {
  other.size_ = 0;
  other.capacity_ = 1;
  other.storage_.heap = nullptr;
}

Column& Column::operator=(Column other) noexcept {
  std::swap(size_, other.size_);
  std::swap(capacity_, other.capacity_);
  std::swap(storage_, other.storage_);
  return *this;
}

Column::~Column() {
  if (capacity_ > 1) delete[] storage_.heap;
}

std::size_t Column::heap_bytes() const { return capacity_ > 1 ? capacity_ * sizeof(HVoxel) : 0; }

void Column::grow(std::uint32_t min_capacity) {
  std::uint32_t cap = capacity_ > 1 ? capacity_ : 2;
  while (cap < min_capacity) cap *= 2;
  auto* heap = new HVoxel[cap];
  std::copy(begin(), end(), heap);
  if (capacity_ > 1) delete[] storage_.heap;
  storage_.heap = heap;
  capacity_ = cap;
}

void Column::insert(std::size_t pos, const HVoxel& v) {
  if (size_ == capacity_) grow(size_ + 1);
  HVoxel* d = data();
  std::copy_backward(d + pos, d + size_, d + size_ + 1);
  d[pos] = v;
  ++size_;
}

void Column::erase(std::size_t first, std::size_t last) {
  HVoxel* d = data();
  std::copy(d + last, d + size_, d + first);
  size_ -= static_cast<std::uint32_t>(last - first);
  if (size_ <= 1 && capacity_ > 1) {  // back to the inline HVoxel: a column rarely regrows
    const HVoxel keep = size_ == 1 ? d[0] : HVoxel{};
    delete[] storage_.heap;
    capacity_ = 1;
    storage_.inline_hvoxel = keep;
  }
}

void Column::clear() { erase(0, size_); }

void Column::merge(const HVoxel& v, float gap, const MapParams& params) {
  // Sorted and disjoint: the HVoxels within `gap` of v form one contiguous run.
  const std::size_t first = lower_bound(v.z_min - gap);
  std::size_t last = first;
  HVoxel united = v;
  const HVoxel* d = data();
  while (last < size_ && d[last].z_min <= v.z_max + gap) {
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
  erase(first + 1, last);
}

bool Column::is_valid() const {
  const HVoxel* d = data();
  for (std::size_t i = 0; i < size_; ++i) {
    if (!(d[i].z_min <= d[i].z_max)) return false;
    if (i > 0 && !(d[i - 1].z_max < d[i].z_min)) return false;
  }
  return true;
}

}  // namespace hmap
