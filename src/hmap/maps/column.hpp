#pragma once
// A map column: the HVoxels of one grid cell, sorted by height and disjoint.
//
// Most cells hold one HVoxel (a wall, the ground: the paper's O(1) best case), so the column
// keeps one HVoxel inline and moves to the heap only when a second arrives; 24 bytes per cell.

#include <cstdint>
#include <span>

#include "hmap/maps/hvoxel.hpp"

namespace hmap {

class Column {
 public:
  Column() = default;
  Column(const Column& other);
  Column(Column&& other) noexcept;
  Column& operator=(Column other) noexcept;
  ~Column();

  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] bool empty() const { return size_ == 0; }
  [[nodiscard]] const HVoxel* begin() const { return data(); }
  [[nodiscard]] const HVoxel* end() const { return data() + size_; }
  [[nodiscard]] const HVoxel& operator[](std::size_t i) const { return data()[i]; }
  [[nodiscard]] HVoxel& operator[](std::size_t i) { return data()[i]; }
  [[nodiscard]] std::span<const HVoxel> hvoxels() const { return {data(), size_}; }
  /// Heap bytes held beyond the inline HVoxel.
  [[nodiscard]] std::size_t heap_bytes() const;

  /// The HVoxel containing height z, or nullptr; binary search, O(log n).
  [[nodiscard]] const HVoxel* find(float z) const {
    const std::size_t i = lower_bound(z);
    return i < size_ && data()[i].z_min <= z ? data() + i : nullptr;
  }
  /// Index of the first HVoxel whose z_max >= z (size() if none).
  [[nodiscard]] std::size_t lower_bound(float z) const {
    // Columns are short: a linear scan beats bisection below a handful of HVoxels.
    const HVoxel* d = data();
    if (size_ <= 8) {
      std::size_t i = 0;
      while (i < size_ && d[i].z_max < z) ++i;
      return i;
    }
    std::size_t lo = 0;
    std::size_t hi = size_;
    while (lo < hi) {
      const std::size_t mid = (lo + hi) / 2;
      if (d[mid].z_max < z) lo = mid + 1; else hi = mid;
    }
    return lo;
  }

  /// Inserts at `pos`; the caller keeps the order (column invariant: sorted, disjoint).
  void insert(std::size_t pos, const HVoxel& v);
  /// Removes HVoxels [first, last).
  void erase(std::size_t first, std::size_t last);
  void clear();
  /// Appends at the top; for loaders, which check the order themselves.
  void push_back(const HVoxel& v) { insert(size_, v); }

  /// III-D merging: unites `v` with every HVoxel overlapping it or closer than `gap` [m] on z;
  /// z_min is the min, z_max the max, counts add, the density is recomputed (eq. 1).
  void merge(const HVoxel& v, float gap, const MapParams& params);

  /// True when sorted by height with gaps between neighbours and each z_min <= z_max.
  [[nodiscard]] bool is_valid() const;

 private:
  [[nodiscard]] const HVoxel* data() const { return capacity_ > 1 ? storage_.heap : &storage_.inline_hvoxel; }
  [[nodiscard]] HVoxel* data() { return capacity_ > 1 ? storage_.heap : &storage_.inline_hvoxel; }
  void grow(std::uint32_t min_capacity);

  std::uint32_t size_ = 0;
  std::uint32_t capacity_ = 1;
  union Storage {
    HVoxel inline_hvoxel;
    HVoxel* heap;
    Storage() : heap(nullptr) {}
  } storage_;
};

}  // namespace hmap
