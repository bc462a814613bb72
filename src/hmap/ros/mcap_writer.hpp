#pragma once
// Writing MCAP files (https://mcap.dev/spec, major version 0): the header, schemas and channels,
// messages in zstd-compressed chunks each followed by its Message Index records, Data End with the
// data section's CRC, a summary (schemas, channels, statistics, chunk indexes), the summary
// offsets, the footer with the summary's CRC, and the closing magic. No file here: the bytes go
// to a sink as they are made (the caller writes them to a file, atomically or not).

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <vector>

namespace hmap::ros::mcap {

/// Receives the file's bytes in order.
using Sink = std::function<void(std::span<const std::uint8_t>)>;

struct WriterOptions {
  std::string profile = "ros2";     ///< the Header's profile ("ros2": ROS 2 well-known encodings)
  std::string library = "hmap";     ///< the Header's library
  std::size_t chunk_bytes = 1 << 20;  ///< [bytes] uncompressed records per chunk before it is closed
  int zstd_level = 3;
};

/// What was written, per channel and in all.
struct WriterStats {
  std::uint64_t messages = 0;
  std::uint64_t chunks = 0;
  std::uint64_t bytes = 0;  ///< the whole file
  std::map<std::uint16_t, std::uint64_t> message_counts;  ///< per channel id
};

/// An MCAP file being written. Schemas and channels are written into the data section when added
/// (outside chunks, so that a reader finds them before any message) and again in the summary.
class Writer {
 public:
  /// Writes the magic and the header to `sink`.
  Writer(Sink sink, WriterOptions options = {});

  /// A schema: `name` (e.g. nav_msgs/msg/OccupancyGrid), `encoding` (ros2msg, jsonschema) and its
  /// text. Returns its id (1, 2, ...).
  std::uint16_t add_schema(const std::string& name, const std::string& encoding, std::string_view data);
  /// A channel on `topic` with messages of schema `schema_id` in `message_encoding` (cdr, json).
  std::uint16_t add_channel(std::uint16_t schema_id, const std::string& topic, const std::string& message_encoding);
  /// One message; log and publish time [ns], in any order: each chunk's and the statistics' start
  /// and end times are the least and greatest log times written into them, and each Message Index
  /// lists its chunk's messages by log time. Throws hmap::Error for an unknown channel or after finish().
  void write(std::uint16_t channel_id, std::uint64_t log_time, std::span<const std::uint8_t> data);
  void write(std::uint16_t channel_id, std::uint64_t log_time, std::string_view data);
  /// Closes the last chunk and writes Data End, the summary, the summary offsets, the footer and
  /// the magic. Nothing may be written after it.
  WriterStats finish();

 private:
  struct SchemaRecord {
    std::uint16_t id;
    std::string name, encoding, data;
  };
  struct ChannelRecord {
    std::uint16_t id, schema_id;
    std::string topic, message_encoding;
  };
  struct ChunkIndex {
    std::uint64_t start_time, end_time, chunk_offset, chunk_length;
    std::map<std::uint16_t, std::uint64_t> message_index_offsets;
    std::uint64_t message_index_length, compressed_size, uncompressed_size;
  };

  void emit(std::span<const std::uint8_t> bytes);
  void close_chunk();

  Sink sink_;
  WriterOptions options_;
  std::uint64_t offset_ = 0;      ///< bytes handed to the sink
  std::uint32_t data_crc_ = 0;    ///< CRC-32 of the data section so far
  bool finished_ = false;
  std::vector<SchemaRecord> schemas_;
  std::vector<ChannelRecord> channels_;
  std::vector<ChunkIndex> chunk_indexes_;
  WriterStats stats_;
  std::uint64_t start_time_ = 0, end_time_ = 0;
  // The open chunk: its uncompressed records and, per channel, (log time, offset in the records).
  std::vector<std::uint8_t> chunk_;
  std::uint64_t chunk_start_ = 0, chunk_end_ = 0;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_messages_;
  std::map<std::uint16_t, std::uint32_t> sequences_;
};

}  // namespace hmap::ros::mcap
