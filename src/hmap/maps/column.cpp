#include "hmap/maps/column.hpp"

#include <algorithm>
#include <utility>

#include "hmap/core/error.hpp"

namespace hmap {

ColumnTile::ColumnTile(const ColumnTile& other) : offset_(other.offset_), capacity_(other.offset_[kCells]) {
  if (capacity_ > 0) {
    hvoxels_ = std::make_unique_for_overwrite<HVoxel[]>(capacity_);
    std::copy_n(other.hvoxels_.get(), capacity_, hvoxels_.get());
  }
}

ColumnTile::ColumnTile(ColumnTile&& other) noexcept
    : offset_(std::exchange(other.offset_, {})),
      capacity_(std::exchange(other.capacity_, std::uint16_t{0})),
      hvoxels_(std::move(other.hvoxels_)) {}

ColumnTile& ColumnTile::operator=(ColumnTile other) noexcept {
  std::swap(offset_, other.offset_);
  std::swap(capacity_, other.capacity_);
  std::swap(hvoxels_, other.hvoxels_);
  return *this;
}

void ColumnTile::grow(std::size_t needed) {
  if (needed > kMaxHVoxels) {
    throw Error("map tile full: more than " + std::to_string(kMaxHVoxels) +
                " HVoxels in one tile of 8x8 cells (is map.point_distance_threshold near 0?)");
  }
  // A quarter more than needed, at least four: amortised O(1) inserts at a small slack.
  const std::size_t capacity = std::min(kMaxHVoxels, std::max(needed + 4, needed + needed / 4));
  auto block = std::make_unique_for_overwrite<HVoxel[]>(capacity);
  if (hvoxels_) std::copy_n(hvoxels_.get(), offset_[kCells], block.get());
  hvoxels_ = std::move(block);
  capacity_ = static_cast<std::uint16_t>(capacity);
}

void ColumnTile::insert(int local, std::size_t pos, const HVoxel& v) {
  const std::size_t total = offset_[kCells];
  if (total + 1 > capacity_) grow(total + 1);
  HVoxel* d = hvoxels_.get();
  const std::size_t at = offset_[local] + pos;
  std::copy_backward(d + at, d + total, d + total + 1);
  d[at] = v;
  for (int k = local + 1; k <= kCells; ++k) ++offset_[k];
}

void ColumnTile::erase(int local, std::size_t first, std::size_t last) {
  if (first >= last) return;
  const std::size_t total = offset_[kCells];
  HVoxel* d = hvoxels_.get();
  const std::size_t from = offset_[local] + first;
  const std::size_t to = offset_[local] + last;
  std::copy(d + to, d + total, d + from);
  const auto removed = static_cast<std::uint16_t>(last - first);
  for (int k = local + 1; k <= kCells; ++k) offset_[k] = static_cast<std::uint16_t>(offset_[k] - removed);
}

void ColumnTile::shrink_to_fit() {
  const std::size_t total = offset_[kCells];
  if (total == capacity_) return;
  if (total == 0) {
    hvoxels_.reset();
    capacity_ = 0;
    return;
  }
  auto block = std::make_unique_for_overwrite<HVoxel[]>(total);
  std::copy_n(hvoxels_.get(), total, block.get());
  hvoxels_ = std::move(block);
  capacity_ = static_cast<std::uint16_t>(total);
}

}  // namespace hmap
