#pragma once
// Internal to hmap::ros: a ROS 1 bag (format 2.0, http://wiki.ros.org/Bags/Format/2.0) read
// record by record from its first byte, without its index: what a recorder killed before it wrote
// the index leaves, or a bag whose index is damaged. Reading stops at the first record or chunk
// that is cut off or malformed; every length is checked against the bytes that remain, and a
// compressed chunk (bz2, lz4) is decompressed as its data comes, never to more than it states.
// Plain C++17 (rosbag_access.cpp, which decodes the messages with ROS's serialization, includes it).

#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <vector>

namespace hmap::ros::access {

struct ScannedConnection {
  std::string topic;
  std::string type;    ///< e.g. sensor_msgs/PointCloud2
  std::string md5sum;
};

inline constexpr std::uint32_t kTopLevel = std::numeric_limits<std::uint32_t>::max();

/// One whole message data record (op 0x02).
struct ScannedMessage {
  std::uint32_t conn = 0;
  std::uint64_t time_ns = 0;           ///< the record's time [ns]
  std::uint32_t chunk = kTopLevel;     ///< compressed chunk it is in (index into chunks), or kTopLevel: `offset` is in the file
  std::uint64_t offset = 0;            ///< of the message's bytes, in the file or in the decompressed chunk
  std::uint32_t length = 0;
};

/// A compressed chunk whose messages were read.
struct ScannedChunk {
  std::string compression;       ///< bz2 or lz4
  std::uint64_t data_at = 0;     ///< [byte] of its compressed data in the file
  std::uint32_t data_length = 0;
  std::uint32_t size = 0;        ///< uncompressed [bytes]
};

struct BagScan {
  std::map<std::uint32_t, ScannedConnection> connections;
  std::vector<ScannedChunk> chunks;         ///< compressed ones only
  std::vector<ScannedMessage> messages;     ///< in file order
  std::size_t chunk_count = 0;              ///< chunks read, whole or (uncompressed) up to the cut
  std::set<std::string> compressions;       ///< of those chunks
  bool has_header = false;                  ///< the file header record (op 0x03) was read whole
  std::uint64_t index_pos = 0;              ///< the file header's index_pos (0: the index was never written)
  std::uint64_t end = 0;                    ///< [byte] the readable part ends here
  std::uint64_t file_size = 0;
  std::string stop;                         ///< what is at `end` when end < file_size, e.g. "a chunk cut off"
};

/// Reads the records of `bytes` (a whole bag file) up to the first one that is cut off or malformed.
[[nodiscard]] BagScan scan_bag(std::string_view bytes);

/// Decompresses `in` (a bz2 or lz4 chunk's data) into `out`; false unless it gives exactly `size`
/// bytes. `out` grows with the output, so a damaged size allocates no more than the data yields.
[[nodiscard]] bool decompress_chunk(const std::string& compression, std::string_view in, std::uint32_t size, std::string& out);

/// The bytes of scanned messages, with the last decompressed chunk kept (thread-safe).
class ScannedMessages {
 public:
  ScannedMessages(std::string file, BagScan scan) : file_(std::move(file)), scan_(std::move(scan)) {}
  [[nodiscard]] const BagScan& scan() const { return scan_; }
  /// A copy of message k's bytes (its chunk decompressed when it is not the last one used).
  [[nodiscard]] std::vector<std::uint8_t> bytes(std::size_t k) const;

 private:
  std::string file_;
  BagScan scan_;
  mutable std::mutex mutex_;
  mutable std::uint32_t cached_chunk_ = kTopLevel;
  mutable std::string cached_;
};

}  // namespace hmap::ros::access
