#pragma once
// MCAP files (https://mcap.dev/spec, major version 0): the records, chunks uncompressed, zstd or
// lz4 (frame format), their CRCs, the summary section and its chunk indexes when present, a linear
// scan of the data section when not (a file cut off by a crash reads up to its last whole message
// and says so). Every length is checked against the bytes that hold it before anything is
// allocated; anything wrong is an InputError naming the file and the byte.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <span>
#include <string>
#include <vector>

namespace hmap::ros::mcap {

/// The bytes of a file, read where asked (a file on disk, or a buffer for tests and fuzzing).
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  [[nodiscard]] virtual std::uint64_t size() const = 0;
  /// Copies bytes [offset, offset + out.size()) into `out`; the caller has checked the range.
  virtual void read(std::uint64_t offset, std::span<std::uint8_t> out) const = 0;
};

[[nodiscard]] std::shared_ptr<const ByteSource> file_source(const std::filesystem::path& path);
/// A copy of `bytes`.
[[nodiscard]] std::shared_ptr<const ByteSource> memory_source(std::span<const std::uint8_t> bytes);

inline constexpr std::uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', 0x30, '\r', '\n'};

// Record opcodes (spec: "Records"), shared by the reader and the writer.
inline constexpr std::uint8_t kHeader = 0x01;
inline constexpr std::uint8_t kFooter = 0x02;
inline constexpr std::uint8_t kSchema = 0x03;
inline constexpr std::uint8_t kChannel = 0x04;
inline constexpr std::uint8_t kMessage = 0x05;
inline constexpr std::uint8_t kChunk = 0x06;
inline constexpr std::uint8_t kMessageIndex = 0x07;
inline constexpr std::uint8_t kChunkIndex = 0x08;
inline constexpr std::uint8_t kStatistics = 0x0B;
inline constexpr std::uint8_t kSummaryOffset = 0x0E;
inline constexpr std::uint8_t kDataEnd = 0x0F;

struct Schema {
  std::uint16_t id = 0;
  std::string name;      ///< e.g. sensor_msgs/msg/PointCloud2
  std::string encoding;  ///< e.g. ros2msg
};

struct Channel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;  ///< cdr for ROS 2
};

struct ChunkInfo {
  std::uint64_t record_offset = 0;    ///< where the chunk record starts in the file
  std::uint64_t records_offset = 0;   ///< where its (compressed) records start
  std::uint64_t compressed_size = 0;  ///< [bytes]
  std::uint64_t uncompressed_size = 0;
  std::uint32_t uncompressed_crc = 0;  ///< 0: not written
  std::string compression;             ///< "", zstd or lz4
  std::uint64_t start_time = 0;        ///< [ns] the chunk record's message start time
  std::uint64_t end_time = 0;          ///< [ns] and end time
  /// [ns] the chunk index's message start and end times (the summary's); the record's when the
  /// data section was scanned. A whole file has them equal.
  std::uint64_t index_start_time = 0, index_end_time = 0;
  std::set<std::uint16_t> channels;    ///< from the chunk index; empty: unknown (look inside)
  /// Where each channel's Message Index record for this chunk lies in the file (from the chunk
  /// index): the messages are then listed without decompressing the chunk.
  std::map<std::uint16_t, std::uint64_t> message_indexes;
};

/// Where one message's data lies: in chunk `chunk`'s uncompressed records, or in the file itself
/// (chunk = kNoChunk).
struct MessageRef {
  static constexpr std::size_t kNoChunk = static_cast<std::size_t>(-1);
  std::uint64_t log_time = 0;  ///< [ns]
  std::uint16_t channel = 0;
  std::size_t chunk = kNoChunk;
  /// Length kFromRecord: listed by a Message Index, whose offset is the message record's, not
  /// its data's; read() takes the length from the record and checks it there.
  static constexpr std::uint64_t kFromRecord = static_cast<std::uint64_t>(-1);
  std::uint64_t offset = 0;  ///< of the message data (of the message record when length is kFromRecord)
  std::uint64_t length = 0;
};

struct Info {
  std::map<std::uint16_t, Schema> schemas;
  std::map<std::uint16_t, Channel> channels;
  std::map<std::uint16_t, std::uint64_t> message_counts;  ///< per channel
  std::uint64_t messages = 0;
  std::uint64_t start_time = 0;  ///< [ns] first message's log time
  std::uint64_t end_time = 0;
  std::vector<ChunkInfo> chunks;
  bool indexed = false;               ///< read from the summary section (else a linear scan)
  std::vector<std::string> warnings;  ///< e.g. cut off
};

/// An MCAP file open for reading. Not thread-safe (it keeps the last chunk, decompressed as far as
/// the messages read so far needed).
class Reader {
 public:
  /// Checks the magic, the header and the footer, reads the summary when there is one (else scans
  /// the data section), and checks the data section's CRC when written. Throws InputError(name, ...).
  Reader(std::shared_ptr<const ByteSource> source, std::string name);
  ~Reader();
  Reader(Reader&&) noexcept;
  Reader& operator=(Reader&&) noexcept;

  [[nodiscard]] const Info& info() const { return info_; }
  /// The messages of `channels` in file order (skipping chunks whose index says they hold none;
  /// from the chunks' Message Index records when the summary points to them, so that listing
  /// does not decompress the chunks that reading will).
  [[nodiscard]] std::vector<MessageRef> messages(const std::set<std::uint16_t>& channels) const;
  /// One message's data. When the data section's CRC was checked at opening (every byte of every
  /// chunk as written), a zstd chunk is decompressed only as far as the message ends, and on from
  /// there for a later message of the same chunk (a /tf message before a large cloud costs a block,
  /// not the chunk); otherwise each chunk is decompressed whole and its own CRC checked.
  [[nodiscard]] std::vector<std::uint8_t> read(const MessageRef& ref) const;

 private:
  void read_summary(std::uint64_t summary_start, std::uint64_t summary_end);
  void scan_data_section();
  struct ChunkCache;
  /// Chunk `chunk`'s records decompressed at least up to byte `needed` (clamped to the chunk's
  /// size; every byte when partial reads are not allowed).
  std::span<const std::uint8_t> chunk_records(std::size_t chunk, std::uint64_t needed = UINT64_MAX) const;
  void walk_chunk(std::size_t chunk, const std::set<std::uint16_t>* channels, std::vector<MessageRef>* out);
  /// Appends the messages of `channels` in chunk `chunk` from its Message Index records, in
  /// record order; false (nothing appended) when a channel the chunk holds has no index.
  bool list_from_indexes(std::size_t chunk, const std::set<std::uint16_t>& channels, std::vector<MessageRef>* out) const;

  std::shared_ptr<const ByteSource> source_;
  std::string name_;
  Info info_;
  std::vector<MessageRef> scanned_;  ///< every message, when the data section was scanned
  bool data_crc_checked_ = false;  ///< the Data End's CRC was written and matched at opening
  mutable std::unique_ptr<ChunkCache> cache_;
};

/// A chunk's records uncompressed: `compression` "", "zstd" or "lz4"; the result must be
/// `uncompressed_size` bytes with the CRC `crc` (0: unchecked). Throws InputError(name, position, ...).
[[nodiscard]] std::vector<std::uint8_t> decompress_chunk(std::span<const std::uint8_t> data, const std::string& compression,
                                                         std::uint64_t uncompressed_size, std::uint32_t crc,
                                                         const std::string& name, const std::string& position);

}  // namespace hmap::ros::mcap
