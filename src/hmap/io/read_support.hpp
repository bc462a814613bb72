#pragma once
// Shared by the readers of hmap::io: a whole file in memory or streamed as fixed-size records,
// number parsing that allocates nothing, binary scalars of either endianness. Internal: the public
// API is in the reader headers.

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "hmap/core/types.hpp"

namespace hmap::detail {

/// Inputs hold at most this much (the readers keep a file whole in memory).
inline constexpr std::size_t kMaxInputBytes = std::size_t{4} << 30;

/// What a stat() mode is, for messages: "a regular file", "a pipe or FIFO", "a character device".
[[nodiscard]] std::string_view file_kind(unsigned mode);

/// The whole file, read with one read() into one buffer sized by fstat; "-" is standard input.
/// Only regular files (and standard input) are read: a device, FIFO, pipe, socket or folder is
/// refused, and a FIFO never blocks in open(). Throws InputError naming the file when it cannot be
/// opened or read, is not a regular file, or holds more than `max_bytes`.
[[nodiscard]] std::string read_file_bytes(const std::filesystem::path& path, std::size_t max_bytes = kMaxInputBytes);

/// Bytes read_file_records hands over at most at a time.
inline constexpr std::size_t kChunkBytes = std::size_t{256} << 10;

/// The file (or standard input, "-") in pieces of whole `record_bytes` records, at most
/// kChunkBytes each, handed to `consume` in order, without holding the whole file: for formats
/// that are a run of fixed-size records (KITTI's .bin). The same inputs are refused as by
/// read_file_bytes. Returns the bytes read: when that is not a multiple of `record_bytes`, the
/// trailing part record was not handed over. `size_hint`, if given, receives a regular file's
/// size (0 for standard input) before anything is consumed.
std::size_t read_file_records(const std::filesystem::path& path, std::size_t record_bytes,
                              const std::function<void(std::span<const char>)>& consume,
                              std::size_t max_bytes = kMaxInputBytes, std::size_t* size_hint = nullptr);

/// Parses the whole token as a decimal number ("1.5", "-2e3", "+4", "nan", "inf").
/// Returns false for anything else, including an empty token or trailing characters.
[[nodiscard]] bool parse_double(std::string_view token, double& value);

/// Parses the whole token as a non-negative decimal integer.
[[nodiscard]] bool parse_uint(std::string_view token, std::uint64_t& value);

/// Splits `line` at runs of spaces and tabs into `tokens` (cleared first; its capacity is reused).
void split_whitespace(std::string_view line, std::vector<std::string_view>& tokens);

/// Walks a text buffer line by line; lines lose their '\n' and a trailing '\r'.
class LineReader {
 public:
  explicit LineReader(std::string_view text, std::size_t first_line_number = 1)
      : text_(text), next_line_number_(first_line_number) {}

  /// The next line, or false at the end of the text.
  bool next(std::string_view& line);
  /// 1-based number of the line last returned by next().
  [[nodiscard]] std::size_t line_number() const { return next_line_number_ - 1; }
  /// Byte offset just past the line last returned (past its '\n').
  [[nodiscard]] std::size_t offset() const { return offset_; }

 private:
  std::string_view text_;
  std::size_t offset_ = 0;
  std::size_t next_line_number_;
};

/// The binary scalar types of PCD and PLY.
enum class ScalarType : std::uint8_t {
  kInt8,
  kUint8,
  kInt16,
  kUint16,
  kInt32,
  kUint32,
  kInt64,
  kUint64,
  kFloat32,
  kFloat64,
};

[[nodiscard]] constexpr std::size_t scalar_size(ScalarType type) {
  switch (type) {
    case ScalarType::kInt8:
    case ScalarType::kUint8:
      return 1;
    case ScalarType::kInt16:
    case ScalarType::kUint16:
      return 2;
    case ScalarType::kInt32:
    case ScalarType::kUint32:
    case ScalarType::kFloat32:
      return 4;
    case ScalarType::kInt64:
    case ScalarType::kUint64:
    case ScalarType::kFloat64:
      return 8;
  }
  return 0;
}

[[nodiscard]] constexpr bool is_integer(ScalarType type) {
  return type != ScalarType::kFloat32 && type != ScalarType::kFloat64;
}

/// A T stored at `p` (any alignment), its bytes reversed when `swap_bytes` (file endianness
/// differs from the machine's).
template <typename T>
[[nodiscard]] inline T load(const char* p, bool swap_bytes) {
  if constexpr (sizeof(T) == 1) {
    T value;
    std::memcpy(&value, p, 1);
    return value;
  } else {
    using Bits = std::conditional_t<sizeof(T) == 2, std::uint16_t,
                                    std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>;
    Bits bits;
    std::memcpy(&bits, p, sizeof bits);
    if (swap_bytes) {
      if constexpr (sizeof(T) == 2) bits = __builtin_bswap16(bits);
      if constexpr (sizeof(T) == 4) bits = __builtin_bswap32(bits);
      if constexpr (sizeof(T) == 8) bits = __builtin_bswap64(bits);
    }
    return std::bit_cast<T>(bits);
  }
}

/// The scalar of `type` at `p`, as a double.
[[nodiscard]] inline double load_scalar(const char* p, ScalarType type, bool swap_bytes) {
  switch (type) {
    case ScalarType::kInt8:
      return load<std::int8_t>(p, swap_bytes);
    case ScalarType::kUint8:
      return load<std::uint8_t>(p, swap_bytes);
    case ScalarType::kInt16:
      return load<std::int16_t>(p, swap_bytes);
    case ScalarType::kUint16:
      return load<std::uint16_t>(p, swap_bytes);
    case ScalarType::kInt32:
      return load<std::int32_t>(p, swap_bytes);
    case ScalarType::kUint32:
      return load<std::uint32_t>(p, swap_bytes);
    case ScalarType::kInt64:
      return static_cast<double>(load<std::int64_t>(p, swap_bytes));
    case ScalarType::kUint64:
      return static_cast<double>(load<std::uint64_t>(p, swap_bytes));
    case ScalarType::kFloat32:
      return load<float>(p, swap_bytes);
    case ScalarType::kFloat64:
      return load<double>(p, swap_bytes);
  }
  return 0.0;
}

/// True when a file written little-endian must be byte-swapped on this machine.
inline constexpr bool kSwapLittleEndian = std::endian::native == std::endian::big;

/// True when (x, y, z) is finite in single precision (false for NaN and beyond FLT_MAX, where the
/// float cast is undefined).
inline bool finite_as_float(double x, double y, double z) {
  constexpr double kMax = 3.4028234663852886e38;  // FLT_MAX
  return std::abs(x) <= kMax && std::abs(y) <= kMax && std::abs(z) <= kMax;
}

/// Appends (x, y, z) when it is finite in single precision; otherwise counts it in `dropped`.
inline void append_if_finite(PointCloud& cloud, double x, double y, double z, std::size_t& dropped) {
  if (finite_as_float(x, y, z)) {
    cloud.emplace_back(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
  } else {
    ++dropped;
  }
}

/// "line 12"
[[nodiscard]] inline std::string line_position(std::size_t line_number) {
  return "line " + std::to_string(line_number);
}
/// "byte 4096"
[[nodiscard]] inline std::string byte_position(std::size_t offset) {
  return "byte " + std::to_string(offset);
}

/// The token, cut to at most 40 characters, in quotes, for an error message.
[[nodiscard]] std::string quoted(std::string_view token);

}  // namespace hmap::detail
