#pragma once
// Map columns: the HVoxels of one grid cell, sorted by height and disjoint.
//
// In the map, the columns of a tile are packed into one buffer (`ColumnTile`): 65 two-byte
// offsets say where each of its 64 columns starts, so an empty cell costs two bytes and a column
// of n HVoxels exactly 16·n bytes, with one allocation per tile instead of one per column.
// `ColumnView` reads a column wherever it lives; `TileColumn` edits one column of a tile;
// `Column` is a column standing alone (scratch work, tests). The edits of the paper's III-D
// (merging) and III-E (extrusion) are written once, over any of the editable kinds.

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "hmap/maps/hvoxel.hpp"

namespace hmap {

/// Index of the first HVoxel of `d[0, n)` whose z_max >= z (n if none).
[[nodiscard]] inline std::size_t column_lower_bound(const HVoxel* d, std::size_t n, float z) {
  // Columns are short: a linear scan beats bisection below a handful of HVoxels.
  if (n <= 8) {
    std::size_t i = 0;
    while (i < n && d[i].z_max < z) ++i;
    return i;
  }
  std::size_t lo = 0;
  std::size_t hi = n;
  while (lo < hi) {
    const std::size_t mid = (lo + hi) / 2;
    if (d[mid].z_max < z) lo = mid + 1; else hi = mid;
  }
  return lo;
}

/// The read-only queries every kind of column answers, over `data()` and `size()`.
template <typename Derived>
class ColumnQueries {
 public:
  [[nodiscard]] bool empty() const { return self().size() == 0; }
  [[nodiscard]] const HVoxel* begin() const { return self().data(); }
  [[nodiscard]] const HVoxel* end() const { return self().data() + self().size(); }
  [[nodiscard]] const HVoxel& operator[](std::size_t i) const { return self().data()[i]; }
  [[nodiscard]] std::span<const HVoxel> hvoxels() const { return {self().data(), self().size()}; }
  /// The HVoxel containing height z, or nullptr; O(log n).
  [[nodiscard]] const HVoxel* find(float z) const {
    const std::size_t i = lower_bound(z);
    return i < self().size() && self().data()[i].z_min <= z ? self().data() + i : nullptr;
  }
  /// Index of the first HVoxel whose z_max >= z (size() if none).
  [[nodiscard]] std::size_t lower_bound(float z) const { return column_lower_bound(self().data(), self().size(), z); }
  /// True when sorted by height with gaps between neighbours and each z_min <= z_max.
  [[nodiscard]] bool is_valid() const {
    const HVoxel* d = self().data();
    for (std::size_t i = 0; i < self().size(); ++i) {
      if (!(d[i].z_min <= d[i].z_max)) return false;
      if (i > 0 && !(d[i - 1].z_max < d[i].z_min)) return false;
    }
    return true;
  }

 private:
  [[nodiscard]] const Derived& self() const { return static_cast<const Derived&>(*this); }
};

/// A column to read, wherever it is stored; valid until that storage changes. Default: empty.
class ColumnView : public ColumnQueries<ColumnView> {
 public:
  ColumnView() = default;
  ColumnView(const HVoxel* data, std::size_t size) : data_(data), size_(size) {}
  [[nodiscard]] const HVoxel* data() const { return data_; }
  [[nodiscard]] std::size_t size() const { return size_; }

 private:
  const HVoxel* data_ = nullptr;
  std::size_t size_ = 0;
};

/// III-D merging: unites `v` with every HVoxel of `column` overlapping it or closer than `gap`
/// [m] on z; z_min is the min, z_max the max, counts add, the density is recomputed (eq. 1).
/// `column` is any editable column (data(), size(), insert(pos, v), erase(first, last)).
template <typename EditableColumn>
void merge_into(EditableColumn& column, const HVoxel& v, float gap, const MapParams& params) {
  // Sorted and disjoint: the HVoxels within `gap` of v form one contiguous run.
  const std::size_t n = column.size();
  const HVoxel* d = column.data();
  const std::size_t first = column_lower_bound(d, n, v.z_min - gap);
  std::size_t last = first;
  HVoxel united = v;
  while (last < n && d[last].z_min <= v.z_max + gap) {
    united.z_min = std::min(united.z_min, d[last].z_min);
    united.z_max = std::max(united.z_max, d[last].z_max);
    united.count += d[last].count;
    ++last;
  }
  update_density(united, params);
  if (first == last) {
    column.insert(first, united);
    return;
  }
  column.data()[first] = united;
  if (last > first + 1) column.erase(first + 1, last);
}

/// A column standing alone, owning its HVoxels.
class Column : public ColumnQueries<Column> {
 public:
  using ColumnQueries<Column>::operator[];
  [[nodiscard]] const HVoxel* data() const { return hvoxels_.data(); }
  [[nodiscard]] HVoxel* data() { return hvoxels_.data(); }
  [[nodiscard]] std::size_t size() const { return hvoxels_.size(); }
  [[nodiscard]] HVoxel& operator[](std::size_t i) { return hvoxels_[i]; }
  [[nodiscard]] ColumnView view() const { return {data(), size()}; }
  /// Heap bytes held (the buffer and the allocator's 16-byte header).
  [[nodiscard]] std::size_t heap_bytes() const {
    return hvoxels_.capacity() == 0 ? 0 : hvoxels_.capacity() * sizeof(HVoxel) + 16;
  }

  /// Inserts at `pos`; the caller keeps the order (column invariant: sorted, disjoint).
  void insert(std::size_t pos, const HVoxel& v) { hvoxels_.insert(hvoxels_.begin() + static_cast<std::ptrdiff_t>(pos), v); }
  /// Removes HVoxels [first, last).
  void erase(std::size_t first, std::size_t last) {
    hvoxels_.erase(hvoxels_.begin() + static_cast<std::ptrdiff_t>(first), hvoxels_.begin() + static_cast<std::ptrdiff_t>(last));
  }
  void clear() { hvoxels_.clear(); }
  /// Appends at the top; for loaders, which check the order themselves.
  void push_back(const HVoxel& v) { hvoxels_.push_back(v); }
  /// III-D merging (merge_into).
  void merge(const HVoxel& v, float gap, const MapParams& params) { merge_into(*this, v, gap, params); }

  friend bool operator==(const Column& a, const Column& b) { return a.hvoxels_ == b.hvoxels_; }

 private:
  std::vector<HVoxel> hvoxels_;
};

/// The columns of one map tile, packed: column k is hvoxels[offset[k], offset[k + 1]).
/// The offsets are 16-bit while the tile holds at most 65,535 HVoxels (every tile of a usual map:
/// an average of 1,023 per column); a tile that grows past it (a height gap near 0 on tall
/// walls) moves them to a 32-bit array of its own.
class ColumnTile {
 public:
  static constexpr int kCells = 64;
  /// The most HVoxels a tile can hold (inserting beyond throws hmap::Error).
  static constexpr std::size_t kMaxHVoxels = 0xFFFFFFFFU;

  ColumnTile() = default;
  ColumnTile(const ColumnTile& other);
  /// Leaves `other` empty.
  ColumnTile(ColumnTile&& other) noexcept;
  ColumnTile& operator=(ColumnTile other) noexcept;
  ~ColumnTile() = default;

  [[nodiscard]] ColumnView column(int local) const {
    return {hvoxels_ ? hvoxels_.get() + offset(local) : nullptr, size(local)};
  }
  [[nodiscard]] std::size_t size(int local) const { return offset(local + 1) - offset(local); }
  [[nodiscard]] HVoxel* data(int local) { return hvoxels_ ? hvoxels_.get() + offset(local) : nullptr; }
  /// True when no column holds an HVoxel.
  [[nodiscard]] bool empty() const { return offset(kCells) == 0; }
  [[nodiscard]] std::size_t hvoxel_count() const { return offset(kCells); }
  /// Heap bytes held beyond the tile object (the HVoxel buffer, any 32-bit offsets, and the
  /// allocator's 16-byte header of each).
  [[nodiscard]] std::size_t heap_bytes() const {
    return (capacity_ == 0 ? 0 : capacity_ * sizeof(HVoxel) + 16) +
           (wide_ ? (kCells + 1) * sizeof(std::uint32_t) + 16 : 0);
  }

  /// Inserts `v` at index `pos` of column `local`.
  void insert(int local, std::size_t pos, const HVoxel& v);
  /// Removes HVoxels [first, last) of column `local`.
  void erase(int local, std::size_t first, std::size_t last);
  /// Gives the buffer back to the allocator down to the HVoxels held.
  void shrink_to_fit();

 private:
  [[nodiscard]] std::size_t offset(int k) const {
    return wide_ ? wide_[static_cast<std::size_t>(k)] : offset_[static_cast<std::size_t>(k)];
  }
  void grow(std::size_t needed);

  std::array<std::uint16_t, kCells + 1> offset_{};  // while wide_ is null
  std::uint32_t capacity_ = 0;
  std::unique_ptr<HVoxel[]> hvoxels_;
  std::unique_ptr<std::uint32_t[]> wide_;  // kCells + 1 offsets, once past 65,535 HVoxels
};

/// One column of a tile, to change it; valid while the tile lives.
class TileColumn : public ColumnQueries<TileColumn> {
 public:
  using ColumnQueries<TileColumn>::operator[];
  TileColumn(ColumnTile& tile, int local) : tile_(&tile), local_(local) {}
  [[nodiscard]] const HVoxel* data() const { return tile_->data(local_); }
  [[nodiscard]] HVoxel* data() { return tile_->data(local_); }
  [[nodiscard]] std::size_t size() const { return tile_->size(local_); }
  [[nodiscard]] HVoxel& operator[](std::size_t i) { return data()[i]; }
  [[nodiscard]] ColumnView view() const { return tile_->column(local_); }

  void insert(std::size_t pos, const HVoxel& v) { tile_->insert(local_, pos, v); }
  void erase(std::size_t first, std::size_t last) { tile_->erase(local_, first, last); }
  void clear() { erase(0, size()); }
  void push_back(const HVoxel& v) { insert(size(), v); }
  void merge(const HVoxel& v, float gap, const MapParams& params) { merge_into(*this, v, gap, params); }

 private:
  ColumnTile* tile_;
  int local_;
};

}  // namespace hmap
