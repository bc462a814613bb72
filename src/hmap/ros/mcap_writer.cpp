#include "hmap/ros/mcap_writer.hpp"

#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <memory>

#include "hmap/core/error.hpp"
#include "hmap/ros/mcap_reader.hpp"

namespace hmap::ros::mcap {

namespace {

/// One record's content, little endian, as the spec lays out its fields.
class Record {
 public:
  explicit Record(std::uint8_t opcode) : bytes_(9, 0) { bytes_[0] = opcode; }
  template <typename T>
  Record& put(T v) {
    for (std::size_t i = 0; i < sizeof(T); ++i) bytes_.push_back(static_cast<std::uint8_t>(static_cast<std::uint64_t>(v) >> (8 * i)));
    return *this;
  }
  Record& raw(std::span<const std::uint8_t> b) {
    bytes_.insert(bytes_.end(), b.begin(), b.end());
    return *this;
  }
  Record& raw(std::string_view s) { return raw(std::span(reinterpret_cast<const std::uint8_t*>(s.data()), s.size())); }
  /// A string or byte array with a u32 length prefix.
  Record& str(std::string_view s) { return put(static_cast<std::uint32_t>(s.size())).raw(s); }
  /// The record with its opcode and content length filled in.
  const std::vector<std::uint8_t>& done() {
    const std::uint64_t length = bytes_.size() - 9;
    for (int i = 0; i < 8; ++i) bytes_[1 + i] = static_cast<std::uint8_t>(length >> (8 * i));
    return bytes_;
  }

 private:
  std::vector<std::uint8_t> bytes_;
};

std::uint32_t crc32_of(std::uint32_t crc, std::span<const std::uint8_t> b) {
  return static_cast<std::uint32_t>(crc32_z(crc, b.data(), b.size()));
}

std::vector<std::uint8_t> schema_record(std::uint16_t id, const std::string& name, const std::string& encoding,
                                        const std::string& data) {
  Record r(kSchema);
  r.put(id).str(name).str(encoding).str(data);
  return r.done();
}

std::vector<std::uint8_t> channel_record(std::uint16_t id, std::uint16_t schema_id, const std::string& topic,
                                         const std::string& encoding) {
  Record r(kChannel);
  r.put(id).put(schema_id).str(topic).str(encoding).put(std::uint32_t{0});  // metadata: an empty map
  return r.done();
}

}  // namespace

Writer::Writer(Sink sink, WriterOptions options) : sink_(std::move(sink)), options_(std::move(options)) {
  if (options_.chunk_bytes == 0) throw Error("MCAP writer: chunk_bytes must be positive");
  emit(kMagic);
  Record header(kHeader);
  header.str(options_.profile).str(options_.library);
  emit(header.done());
}

void Writer::emit(std::span<const std::uint8_t> bytes) {
  if (bytes.empty()) return;
  sink_(bytes);
  offset_ += bytes.size();
  if (!finished_) data_crc_ = crc32_of(data_crc_, bytes);
}

std::uint16_t Writer::add_schema(const std::string& name, const std::string& encoding, std::string_view data) {
  if (finished_) throw Error("MCAP writer: add_schema after finish");
  if (schemas_.size() >= 0xFFFE) throw Error("MCAP writer: too many schemas");
  const auto id = static_cast<std::uint16_t>(schemas_.size() + 1);  // 0 means "no schema"
  schemas_.push_back({id, name, encoding, std::string(data)});
  emit(schema_record(id, name, encoding, schemas_.back().data));
  return id;
}

std::uint16_t Writer::add_channel(std::uint16_t schema_id, const std::string& topic, const std::string& message_encoding) {
  if (finished_) throw Error("MCAP writer: add_channel after finish");
  if (schema_id == 0 || schema_id > schemas_.size()) throw Error("MCAP writer: channel " + topic + " names no schema");
  if (channels_.size() >= 0xFFFF) throw Error("MCAP writer: too many channels");
  const auto id = static_cast<std::uint16_t>(channels_.size());
  channels_.push_back({id, schema_id, topic, message_encoding});
  emit(channel_record(id, schema_id, topic, message_encoding));
  return id;
}

void Writer::write(std::uint16_t channel_id, std::uint64_t log_time, std::string_view data) {
  write(channel_id, log_time, std::span(reinterpret_cast<const std::uint8_t*>(data.data()), data.size()));
}

void Writer::write(std::uint16_t channel_id, std::uint64_t log_time, std::span<const std::uint8_t> data) {
  if (finished_) throw Error("MCAP writer: write after finish");
  if (channel_id >= channels_.size()) throw Error("MCAP writer: no channel " + std::to_string(channel_id));
  if (chunk_.empty()) chunk_start_ = chunk_end_ = log_time;
  chunk_start_ = std::min(chunk_start_, log_time);
  chunk_end_ = std::max(chunk_end_, log_time);
  if (stats_.messages == 0) start_time_ = end_time_ = log_time;
  start_time_ = std::min(start_time_, log_time);
  end_time_ = std::max(end_time_, log_time);
  chunk_messages_[channel_id].emplace_back(log_time, chunk_.size());
  Record r(kMessage);
  r.put(channel_id).put(sequences_[channel_id]++).put(log_time).put(log_time).raw(data);  // publish time = log time
  const auto& rec = r.done();
  chunk_.insert(chunk_.end(), rec.begin(), rec.end());
  ++stats_.messages;
  ++stats_.message_counts[channel_id];
  if (chunk_.size() >= options_.chunk_bytes) close_chunk();
}

void Writer::close_chunk() {
  if (chunk_.empty()) return;
  std::vector<std::uint8_t> compressed(ZSTD_compressBound(chunk_.size()));
  const std::size_t n = ZSTD_compress(compressed.data(), compressed.size(), chunk_.data(), chunk_.size(), options_.zstd_level);
  if (ZSTD_isError(n)) throw Error(std::string("MCAP writer: zstd: ") + ZSTD_getErrorName(n));
  compressed.resize(n);

  ChunkIndex index{};
  index.start_time = chunk_start_;
  index.end_time = chunk_end_;
  index.chunk_offset = offset_;
  index.compressed_size = compressed.size();
  index.uncompressed_size = chunk_.size();
  Record chunk(kChunk);
  chunk.put(chunk_start_).put(chunk_end_).put(std::uint64_t{chunk_.size()}).put(crc32_of(0, chunk_)).str("zstd");
  chunk.put(std::uint64_t{compressed.size()}).raw(compressed);
  const auto& chunk_bytes = chunk.done();
  index.chunk_length = chunk_bytes.size();
  emit(chunk_bytes);

  // One Message Index per channel in the chunk: (log time, offset of the message record in the
  // uncompressed records), in log time order (messages may be written out of it, e.g. /tf of an
  // unsorted trajectory), so that a reader seeking a time can search it.
  const std::uint64_t indexes_start = offset_;
  for (auto& [channel, entries] : chunk_messages_) {
    std::stable_sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    index.message_index_offsets[channel] = offset_;
    Record mi(kMessageIndex);
    mi.put(channel).put(static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [time, at] : entries) mi.put(time).put(at);
    emit(mi.done());
  }
  index.message_index_length = offset_ - indexes_start;
  chunk_indexes_.push_back(std::move(index));
  ++stats_.chunks;
  chunk_.clear();
  chunk_messages_.clear();
}

WriterStats Writer::finish() {
  if (finished_) throw Error("MCAP writer: finish called twice");
  close_chunk();
  Record data_end(kDataEnd);
  data_end.put(data_crc_);
  finished_ = true;  // the data section ends here: no more CRC
  emit(data_end.done());

  // Summary: schemas, channels, statistics, chunk indexes, each group found by a Summary Offset.
  const std::uint64_t summary_start = offset_;
  std::uint32_t summary_crc = 0;
  struct Group {
    std::uint8_t opcode;
    std::uint64_t start, length;
  };
  std::vector<Group> groups;
  auto put_summary = [&](std::span<const std::uint8_t> b) {
    summary_crc = crc32_of(summary_crc, b);
    emit(b);
  };
  auto group = [&](std::uint8_t opcode, const std::function<void()>& body) {
    const std::uint64_t start = offset_;
    body();
    if (offset_ > start) groups.push_back({opcode, start, offset_ - start});
  };
  group(kSchema, [&] {
    for (const auto& s : schemas_) put_summary(schema_record(s.id, s.name, s.encoding, s.data));
  });
  group(kChannel, [&] {
    for (const auto& c : channels_) put_summary(channel_record(c.id, c.schema_id, c.topic, c.message_encoding));
  });
  group(kStatistics, [&] {
    Record st(kStatistics);
    st.put(stats_.messages).put(static_cast<std::uint16_t>(schemas_.size())).put(static_cast<std::uint32_t>(channels_.size()));
    st.put(std::uint32_t{0}).put(std::uint32_t{0}).put(static_cast<std::uint32_t>(stats_.chunks));  // attachments, metadata, chunks
    st.put(start_time_).put(end_time_);
    st.put(static_cast<std::uint32_t>(stats_.message_counts.size() * 10));
    for (const auto& [channel, count] : stats_.message_counts) st.put(channel).put(count);
    put_summary(st.done());
  });
  group(kChunkIndex, [&] {
    for (const auto& c : chunk_indexes_) {
      Record ci(kChunkIndex);
      ci.put(c.start_time).put(c.end_time).put(c.chunk_offset).put(c.chunk_length);
      ci.put(static_cast<std::uint32_t>(c.message_index_offsets.size() * 10));
      for (const auto& [channel, at] : c.message_index_offsets) ci.put(channel).put(at);
      ci.put(c.message_index_length).str("zstd").put(c.compressed_size).put(c.uncompressed_size);
      put_summary(ci.done());
    }
  });
  const std::uint64_t summary_offset_start = offset_;
  for (const Group& g : groups) {
    Record so(kSummaryOffset);
    so.put(g.opcode).put(g.start).put(g.length);
    put_summary(so.done());
  }
  // The footer's CRC covers the summary through the footer's own summary_offset_start field.
  Record footer(kFooter);
  footer.put(summary_start).put(summary_offset_start).put(std::uint32_t{0});
  std::vector<std::uint8_t> footer_bytes = footer.done();
  summary_crc = crc32_of(summary_crc, std::span(footer_bytes).first(footer_bytes.size() - 4));
  for (int i = 0; i < 4; ++i) footer_bytes[footer_bytes.size() - 4 + i] = static_cast<std::uint8_t>(summary_crc >> (8 * i));
  emit(footer_bytes);
  emit(kMagic);
  stats_.bytes = offset_;
  return stats_;
}

}  // namespace hmap::ros::mcap
