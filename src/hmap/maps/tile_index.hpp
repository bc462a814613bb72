#pragma once
// The index from tile keys to tiles: open addressing with linear probing over a power-of-two
// table of (key, slot) pairs, tiles kept densely in insertion order. A map holds thousands of
// tiles, so the table stays in cache; lookups are a hash and a probe or two.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "hmap/core/types.hpp"

namespace hmap {

/// The tiles of the square of cells within `half_cells` of `center` (tiles of 2^tile_bits cells per
/// edge), row by row in `tiles`, nullptr where find(tile key) has none; `tile_min` is the square's
/// lowest tile and `tiles_wide` its width in tiles. For views that index a window of tiles without
/// a hash lookup per cell.
template <typename Tile, typename Find>
void tile_window(const CellKey& center, std::int32_t half_cells, int tile_bits, Find&& find, CellKey& tile_min,
                 std::int32_t& tiles_wide, std::vector<const Tile*>& tiles) {
  const CellKey lo{(center.i - half_cells) >> tile_bits, (center.j - half_cells) >> tile_bits};
  const CellKey hi{(center.i + half_cells) >> tile_bits, (center.j + half_cells) >> tile_bits};
  tile_min = lo;
  tiles_wide = std::max(hi.i - lo.i, hi.j - lo.j) + 1;
  tiles.assign(static_cast<std::size_t>(tiles_wide) * static_cast<std::size_t>(tiles_wide), nullptr);
  for (std::int32_t ti = 0; ti < tiles_wide; ++ti) {
    for (std::int32_t tj = 0; tj < tiles_wide; ++tj) {
      tiles[static_cast<std::size_t>(ti) * static_cast<std::size_t>(tiles_wide) + static_cast<std::size_t>(tj)] =
          find(CellKey{lo.i + ti, lo.j + tj});
    }
  }
}

template <typename Tile>
class TileIndex {
 public:
  [[nodiscard]] std::size_t size() const { return tiles_.size(); }
  [[nodiscard]] std::size_t table_bytes() const {
    return table_.size() * sizeof(Entry) + keys_.capacity() * sizeof(CellKey) +
           tiles_.capacity() * sizeof(std::unique_ptr<Tile>);
  }

  [[nodiscard]] Tile* find(const CellKey& key) const {
    if (table_.empty()) return nullptr;
    for (std::size_t s = CellKeyHash{}(key) & mask_;; s = (s + 1) & mask_) {
      const Entry& e = table_[s];
      if (e.slot == kEmpty) return nullptr;
      if (e.key == key) return tiles_[e.slot].get();
    }
  }

  /// The tile of `key`, created (value-initialised) if absent.
  Tile& find_or_create(const CellKey& key) {
    if (Tile* t = find(key)) return *t;
    if ((tiles_.size() + 1) * 2 > table_.size()) rehash(table_.empty() ? 64 : table_.size() * 2);
    insert_entry(key, static_cast<std::uint32_t>(tiles_.size()));
    keys_.push_back(key);
    tiles_.push_back(std::make_unique<Tile>());
    return *tiles_.back();
  }

  /// Removes every tile for which pred(tile) is true, keeping the others' order; pred may
  /// change the tiles it keeps.
  template <typename Pred>
  void erase_if(Pred pred) {
    std::size_t kept = 0;
    for (std::size_t k = 0; k < tiles_.size(); ++k) {
      if (pred(*tiles_[k])) continue;
      keys_[kept] = keys_[k];
      tiles_[kept] = std::move(tiles_[k]);
      ++kept;
    }
    keys_.resize(kept);
    tiles_.resize(kept);
    rehash(table_.size());
  }

  void clear() {
    table_.clear();
    keys_.clear();
    tiles_.clear();
    mask_ = 0;
  }

  /// Calls f(key, const Tile&) for every tile, in insertion order.
  template <typename F>
  void for_each(F&& f) const {
    for (std::size_t k = 0; k < tiles_.size(); ++k) f(keys_[k], *tiles_[k]);
  }

 private:
  static constexpr std::uint32_t kEmpty = std::numeric_limits<std::uint32_t>::max();
  struct Entry {
    CellKey key;
    std::uint32_t slot = kEmpty;
  };

  void insert_entry(const CellKey& key, std::uint32_t slot) {
    std::size_t s = CellKeyHash{}(key) & mask_;
    while (table_[s].slot != kEmpty) s = (s + 1) & mask_;
    table_[s] = {key, slot};
  }

  void rehash(std::size_t capacity) {
    table_.assign(capacity, Entry{});
    mask_ = capacity - 1;
    for (std::size_t k = 0; k < keys_.size(); ++k) insert_entry(keys_[k], static_cast<std::uint32_t>(k));
  }

  std::vector<Entry> table_;
  std::size_t mask_ = 0;
  std::vector<CellKey> keys_;
  std::vector<std::unique_ptr<Tile>> tiles_;
};

}  // namespace hmap
