#include "hmap/maps/column.hpp"

#include <algorithm>
#include <utility>

#include "hmap/core/error.hpp"

namespace hmap {

ColumnTile::ColumnTile(const ColumnTile& other)
    : offset_(other.offset_), capacity_(static_cast<std::uint32_t>(other.hvoxel_count())) {
  if (capacity_ > 0) {
    hvoxels_ = std::make_unique_for_overwrite<HVoxel[]>(capacity_);
    std::copy_n(other.hvoxels_.get(), capacity_, hvoxels_.get());
  }
  if (other.wide_) {
    wide_ = std::make_unique_for_overwrite<std::uint32_t[]>(kCells + 1);
    std::copy_n(other.wide_.get(), kCells + 1, wide_.get());
  }
}

ColumnTile::ColumnTile(ColumnTile&& other) noexcept
    : offset_(std::exchange(other.offset_, {})),
      capacity_(std::exchange(other.capacity_, 0U)),
      hvoxels_(std::move(other.hvoxels_)),
      wide_(std::move(other.wide_)) {}

ColumnTile& ColumnTile::operator=(ColumnTile other) noexcept {
  std::swap(offset_, other.offset_);
  std::swap(capacity_, other.capacity_);
  std::swap(hvoxels_, other.hvoxels_);
  std::swap(wide_, other.wide_);
  return *this;
}

void ColumnTile::grow(std::size_t needed) {
  if (needed > kMaxHVoxels) {
    throw Error("map tile full: more than " + std::to_string(kMaxHVoxels) + " HVoxels in one tile of 8x8 cells");
  }
  // A quarter more than needed, at least four: amortised O(1) inserts at a small slack.
  const std::size_t capacity = std::min(kMaxHVoxels, std::max(needed + 4, needed + needed / 4));
  auto block = std::make_unique_for_overwrite<HVoxel[]>(capacity);
  if (hvoxels_) std::copy_n(hvoxels_.get(), hvoxel_count(), block.get());
  hvoxels_ = std::move(block);
  capacity_ = static_cast<std::uint32_t>(capacity);
  if (!wide_ && needed > 0xFFFFU) {  // the 16-bit offsets would wrap: 32-bit from now on
    wide_ = std::make_unique_for_overwrite<std::uint32_t[]>(kCells + 1);
    std::copy(offset_.begin(), offset_.end(), wide_.get());
  }
}

void ColumnTile::insert(int local, std::size_t pos, const HVoxel& v) {
  const std::size_t total = hvoxel_count();
  if (total + 1 > capacity_ || (!wide_ && total + 1 > 0xFFFFU)) grow(total + 1);
  HVoxel* d = hvoxels_.get();
  const std::size_t at = offset(local) + pos;
  std::copy_backward(d + at, d + total, d + total + 1);
  d[at] = v;
  if (wide_) {
    for (int k = local + 1; k <= kCells; ++k) ++wide_[static_cast<std::size_t>(k)];
  } else {
    for (int k = local + 1; k <= kCells; ++k) ++offset_[static_cast<std::size_t>(k)];
  }
}

void ColumnTile::erase(int local, std::size_t first, std::size_t last) {
  if (first >= last) return;
  const std::size_t total = hvoxel_count();
  HVoxel* d = hvoxels_.get();
  const std::size_t from = offset(local) + first;
  const std::size_t to = offset(local) + last;
  std::copy(d + to, d + total, d + from);
  const std::size_t removed = last - first;
  if (wide_) {
    for (int k = local + 1; k <= kCells; ++k) wide_[static_cast<std::size_t>(k)] -= static_cast<std::uint32_t>(removed);
  } else {
    for (int k = local + 1; k <= kCells; ++k) {
      offset_[static_cast<std::size_t>(k)] = static_cast<std::uint16_t>(offset_[static_cast<std::size_t>(k)] - removed);
    }
  }
}

void ColumnTile::shrink_to_fit() {
  const std::size_t total = hvoxel_count();
  if (wide_ && total <= 0xFFFFU) {  // back to 16-bit offsets
    for (std::size_t k = 0; k <= kCells; ++k) offset_[k] = static_cast<std::uint16_t>(wide_[k]);
    wide_.reset();
  }
  if (total == capacity_) return;
  if (total == 0) {
    hvoxels_.reset();
    capacity_ = 0;
    return;
  }
  auto block = std::make_unique_for_overwrite<HVoxel[]>(total);
  std::copy_n(hvoxels_.get(), total, block.get());
  hvoxels_ = std::move(block);
  capacity_ = static_cast<std::uint32_t>(total);
}

}  // namespace hmap
