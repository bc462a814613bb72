#pragma once
// A map column: the HVoxels of one grid cell, sorted by height and disjoint.
//
// Most cells hold one HVoxel (a wall, the ground: the paper's O(1) best case), so a column is
// 16 bytes: either that one HVoxel inline, or a tag, a count and a pointer to the heap. An inline
// HVoxel's z_min is a finite float, so two NaN bit patterns in its place tell "empty" and "on the
// heap" apart. The heap block always holds bit_ceil(max(size, 2)) HVoxels.

#include <bit>
#include <cstdint>
#include <cstring>
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

  [[nodiscard]] std::size_t size() const {
    const std::uint32_t t = tag();
    return t == kEmptyTag ? 0 : t == kHeapTag ? storage_.heap.size : 1;
  }
  [[nodiscard]] bool empty() const { return tag() == kEmptyTag; }
  [[nodiscard]] const HVoxel* begin() const { return data(); }
  [[nodiscard]] const HVoxel* end() const { return data() + size(); }
  [[nodiscard]] const HVoxel& operator[](std::size_t i) const { return data()[i]; }
  [[nodiscard]] HVoxel& operator[](std::size_t i) { return data()[i]; }
  [[nodiscard]] std::span<const HVoxel> hvoxels() const { return {data(), size()}; }
  /// Heap bytes held beyond the inline HVoxel.
  [[nodiscard]] std::size_t heap_bytes() const;

  /// The HVoxel containing height z, or nullptr; binary search, O(log n).
  [[nodiscard]] const HVoxel* find(float z) const {
    const std::size_t i = lower_bound(z);
    return i < size() && data()[i].z_min <= z ? data() + i : nullptr;
  }
  /// Index of the first HVoxel whose z_max >= z (size() if none).
  [[nodiscard]] std::size_t lower_bound(float z) const {
    // Columns are short: a linear scan beats bisection below a handful of HVoxels.
    const HVoxel* d = data();
    const std::size_t n = size();
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

  /// Inserts at `pos`; the caller keeps the order (column invariant: sorted, disjoint).
  void insert(std::size_t pos, const HVoxel& v);
  /// Removes HVoxels [first, last).
  void erase(std::size_t first, std::size_t last);
  void clear();
  /// Appends at the top; for loaders, which check the order themselves.
  void push_back(const HVoxel& v) { insert(size(), v); }

  /// III-D merging: unites `v` with every HVoxel overlapping it or closer than `gap` [m] on z;
  /// z_min is the min, z_max the max, counts add, the density is recomputed (eq. 1).
  void merge(const HVoxel& v, float gap, const MapParams& params);

  /// True when sorted by height with gaps between neighbours and each z_min <= z_max.
  [[nodiscard]] bool is_valid() const;

 private:
  static constexpr std::uint32_t kEmptyTag = 0x7FC00E00U;  // quiet NaN patterns no sensor gives
  static constexpr std::uint32_t kHeapTag = 0x7FC00E01U;
  struct HeapRef {
    std::uint32_t tag;
    std::uint32_t size;
    HVoxel* data;
  };
  union Storage {
    HVoxel inline_hvoxel;
    HeapRef heap;
    Storage() : heap{kEmptyTag, 0, nullptr} {}
  };
  static_assert(sizeof(HVoxel) == 16 && sizeof(HeapRef) == 16);

  [[nodiscard]] std::uint32_t tag() const {
    std::uint32_t t = 0;
    std::memcpy(&t, &storage_, sizeof t);
    return t;
  }
  [[nodiscard]] bool on_heap() const { return tag() == kHeapTag; }
  [[nodiscard]] static std::size_t capacity_for(std::size_t n) { return std::bit_ceil(n < 2 ? std::size_t{2} : n); }
  [[nodiscard]] const HVoxel* data() const { return on_heap() ? storage_.heap.data : &storage_.inline_hvoxel; }
  [[nodiscard]] HVoxel* data() { return on_heap() ? storage_.heap.data : &storage_.inline_hvoxel; }
  /// Moves the HVoxels to a heap block of capacity_for(n) (n >= 2) or inline (n <= 1), keeping
  /// the first min(size, n) of them; sets the size to n.
  void relocate(std::size_t n);

  Storage storage_;
};

}  // namespace hmap
