// The MCAP writer (src/hmap/ros/mcap_writer.hpp) read back by our reader: every record it writes,
// the chunks' and sections' CRCs checked, the summary's indexes used; damage found by the CRCs.

#include "hmap/ros/mcap_writer.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/ros/mcap_reader.hpp"

namespace hmap::ros::mcap {
namespace {

std::vector<std::uint8_t> bytes_of(const std::string& s) { return {s.begin(), s.end()}; }

/// {"k":K}, built by appending (GCC 12 warns falsely, -Wrestrict, on "literal" + std::string&&).
std::string json_k(std::size_t k) {
  std::string s = R"({"k":)";
  s += std::to_string(k);
  s += "}";
  return s;
}

/// The message of the InputError that opening `file` throws ("" when it opens).
std::string open_error(const std::vector<std::uint8_t>& file) {
  try {
    const Reader reader(memory_source(file), "damaged.mcap");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

struct Written {
  std::vector<std::uint8_t> file;
  WriterStats stats;
};

/// Two channels of 50 messages each, in chunks of about 300 bytes (several chunks).
Written two_channels(std::size_t messages_per_channel) {
  Written w;
  WriterOptions options;
  options.chunk_bytes = 300;
  Writer writer([&](std::span<const std::uint8_t> b) { w.file.insert(w.file.end(), b.begin(), b.end()); }, options);
  const auto a = writer.add_schema("std_msgs/msg/String", "ros2msg", "string data\n");
  const auto b = writer.add_schema("foxglove.Log", "jsonschema", R"({"type":"object"})");
  const auto ca = writer.add_channel(a, "/a", "cdr");
  const auto cb = writer.add_channel(b, "/b", "json");
  for (std::size_t k = 0; k < messages_per_channel; ++k) {
    writer.write(ca, 1000 + k, std::string("a").append(std::to_string(k)));
    writer.write(cb, 2000 + k, json_k(k));
  }
  w.stats = writer.finish();
  return w;
}

TEST(McapWriterTest, ReadBackThroughTheSummaryWithEveryMessageInOrder) {
  const Written w = two_channels(50);
  EXPECT_EQ(w.stats.messages, 100U);
  EXPECT_GT(w.stats.chunks, 3U);
  EXPECT_EQ(w.stats.bytes, w.file.size());
  const Reader reader(memory_source(w.file), "written.mcap");
  const Info& info = reader.info();
  EXPECT_TRUE(info.indexed);  // from the summary's chunk indexes, not a scan
  ASSERT_EQ(info.schemas.size(), 2U);
  EXPECT_EQ(info.schemas.at(1).name, "std_msgs/msg/String");
  EXPECT_EQ(info.schemas.at(2).encoding, "jsonschema");
  ASSERT_EQ(info.channels.size(), 2U);
  EXPECT_EQ(info.channels.at(0).topic, "/a");
  EXPECT_EQ(info.channels.at(1).message_encoding, "json");
  EXPECT_EQ(info.messages, 100U);
  EXPECT_EQ(info.message_counts.at(0), 50U);
  EXPECT_EQ(info.message_counts.at(1), 50U);
  EXPECT_EQ(info.start_time, 1000U);
  EXPECT_EQ(info.end_time, 2049U);
  EXPECT_EQ(info.chunks.size(), w.stats.chunks);
  for (const ChunkInfo& c : info.chunks) EXPECT_EQ(c.compression, "zstd");
  const auto refs = reader.messages({0, 1});
  ASSERT_EQ(refs.size(), 100U);
  std::size_t na = 0, nb = 0;
  for (const MessageRef& r : refs) {
    const auto data = reader.read(r);
    if (r.channel == 0) {
      EXPECT_EQ(data, bytes_of(std::string("a").append(std::to_string(na)))) << na;
      EXPECT_EQ(r.log_time, 1000 + na++);
    } else {
      EXPECT_EQ(data, bytes_of(json_k(nb))) << nb;
      EXPECT_EQ(r.log_time, 2000 + nb++);
    }
  }
}

// A file whose data CRC matches is read a zstd chunk only as far as each message needs (hmap's
// /tf pass before its clouds): small messages at each chunk's start read first, then the large ones
// behind them (the chunk taken up where it stopped, or restarted whole), then all backwards, give
// the bytes written every time. Large = 300 kB of pseudo-random bytes, several zstd blocks each.
TEST(McapWriterTest, MessagesReadInAnyOrderFromPartlyDecompressedChunks) {
  std::vector<std::uint8_t> file;
  WriterOptions options;
  options.chunk_bytes = 1000;  // each chunk closes after its large message
  Writer writer([&](std::span<const std::uint8_t> b) { file.insert(file.end(), b.begin(), b.end()); }, options);
  const auto schema = writer.add_schema("x", "ros2msg", "uint8[] data\n");
  const auto small = writer.add_channel(schema, "/tf", "cdr");
  const auto large = writer.add_channel(schema, "/cloud", "cdr");
  std::vector<std::vector<std::uint8_t>> clouds;
  std::uint32_t state = 12345;
  for (std::uint64_t k = 0; k < 4; ++k) {
    writer.write(small, 10 * k, "tf" + std::to_string(k));
    std::vector<std::uint8_t> cloud(300000 + 1000 * k);
    for (auto& b : cloud) {
      state = state * 1664525U + 1013904223U;
      b = static_cast<std::uint8_t>(state >> 24);
    }
    writer.write(large, 10 * k + 1, cloud);
    clouds.push_back(std::move(cloud));
  }
  (void)writer.finish();
  const Reader reader(memory_source(file), "partial.mcap");
  ASSERT_EQ(reader.info().chunks.size(), 4U);
  const auto tf = reader.messages({small});
  const auto cl = reader.messages({large});
  ASSERT_EQ(tf.size(), 4U);
  ASSERT_EQ(cl.size(), 4U);
  for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(reader.read(tf[k]), bytes_of("tf" + std::to_string(k))) << k;
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(reader.read(tf[k]), bytes_of("tf" + std::to_string(k))) << k;  // the chunk begun here
    EXPECT_EQ(reader.read(cl[k]), clouds[k]) << k;                             // and taken on to its end
  }
  for (std::size_t k = 4; k-- > 0;) {
    EXPECT_EQ(reader.read(cl[k]), clouds[k]) << k;  // whole at once
    EXPECT_EQ(reader.read(tf[k]), bytes_of("tf" + std::to_string(k))) << k;
  }
  // A damaged chunk is still found, by the data section's CRC at opening.
  std::vector<std::uint8_t> hit = file;
  hit[static_cast<std::size_t>(reader.info().chunks[2].records_offset) + 100] ^= 0x10;
  EXPECT_NE(open_error(hit).find("data section CRC mismatch"), std::string::npos) << open_error(hit);
}

// Log times written out of order (a trajectory whose stamps go back, a second channel far
// later): each message reads back with its own time; the statistics' start and end, and each chunk's
// (its record's and its index's), are the least and greatest log times of the messages they hold;
// the Message Index of each chunk lists them by time.
TEST(McapWriterTest, LogTimesAndStatisticsAreThoseOfTheMessagesWritten) {
  std::vector<std::uint8_t> file;
  WriterOptions options;
  options.chunk_bytes = 200;  // a few messages per chunk
  Writer writer([&](std::span<const std::uint8_t> b) { file.insert(file.end(), b.begin(), b.end()); }, options);
  const auto schema = writer.add_schema("x", "ros2msg", "string data\n");
  const auto tf = writer.add_channel(schema, "/tf", "cdr");
  const auto map = writer.add_channel(schema, "/map", "cdr");
  const auto unused = writer.add_channel(schema, "/unused", "cdr");
  // A Unix time in ns (past 2^53: a double would not hold it), jumping back and forth by steps
  // that are not multiples of one another.
  const std::uint64_t t0 = 1'700'000'000'123'456'789ULL;
  std::vector<std::pair<std::uint16_t, std::uint64_t>> written;  // (channel, log time) in file order
  std::map<std::string, std::uint64_t> time_of;                  // by the message's data
  for (std::uint64_t k = 0; k < 40; ++k) {
    const std::uint64_t t = t0 + (k * 7919 % 40) * 1'000'003ULL + k;  // a permutation of 0..39, scaled
    writer.write(tf, t, "tf" + std::to_string(k));
    written.emplace_back(tf, t);
    time_of["tf" + std::to_string(k)] = t;
    if (k % 10 == 9) {
      writer.write(map, t0 + 3'000'000'000ULL - k, "map" + std::to_string(k));
      written.emplace_back(map, t0 + 3'000'000'000ULL - k);
      time_of["map" + std::to_string(k)] = t0 + 3'000'000'000ULL - k;
    }
  }
  const WriterStats stats = writer.finish();
  ASSERT_GT(stats.chunks, 3U);

  const Reader reader(memory_source(file), "times.mcap");
  const Info& info = reader.info();
  ASSERT_TRUE(info.indexed);
  std::uint64_t lo = UINT64_MAX, hi = 0;
  std::map<std::uint16_t, std::uint64_t> counts;
  for (const auto& [channel, t] : written) {
    lo = std::min(lo, t);
    hi = std::max(hi, t);
    ++counts[channel];
  }
  EXPECT_EQ(info.messages, written.size());
  EXPECT_EQ(info.start_time, lo);
  EXPECT_EQ(info.end_time, hi);
  EXPECT_EQ(info.message_counts, counts);  // no entry for the channel without messages
  EXPECT_EQ(info.message_counts.count(unused), 0U);
  EXPECT_EQ(stats.message_counts, counts);

  // Every message with its own log time, as listed from the Message Index records (the summary
  // points to them): each message's data names the time it was written with.
  const auto refs = reader.messages({tf, map});
  ASSERT_EQ(refs.size(), written.size());
  std::set<std::string> seen;
  for (const MessageRef& r : refs) {
    const auto data = reader.read(r);
    const std::string text(data.begin(), data.end());
    ASSERT_EQ(time_of.count(text), 1U) << text;
    EXPECT_EQ(r.log_time, time_of.at(text)) << text;
    EXPECT_EQ(r.channel, text.starts_with("tf") ? tf : map) << text;
    EXPECT_TRUE(seen.insert(text).second) << text;
  }

  // Per chunk: the record's times and the index's are the extremes of its messages.
  std::map<std::size_t, std::pair<std::uint64_t, std::uint64_t>> extremes;
  for (const MessageRef& r : refs) {
    auto [it, fresh] = extremes.try_emplace(r.chunk, r.log_time, r.log_time);
    it->second.first = std::min(it->second.first, r.log_time);
    it->second.second = std::max(it->second.second, r.log_time);
  }
  ASSERT_EQ(extremes.size(), info.chunks.size());
  for (const auto& [chunk, range] : extremes) {
    const ChunkInfo& c = info.chunks.at(chunk);
    EXPECT_EQ(c.start_time, range.first) << chunk;
    EXPECT_EQ(c.end_time, range.second) << chunk;
    EXPECT_EQ(c.index_start_time, range.first) << chunk;
    EXPECT_EQ(c.index_end_time, range.second) << chunk;
    // Each Message Index record (opcode, length, channel, entries' byte length, then (time,
    // offset) pairs) lists its messages by log time.
    for (const auto& [channel, at] : c.message_indexes) {
      auto u64 = [&](std::size_t p) {
        std::uint64_t v = 0;
        for (int i = 7; i >= 0; --i) v = (v << 8) | file.at(p + static_cast<std::size_t>(i));
        return v;
      };
      const auto begin = static_cast<std::size_t>(at);
      ASSERT_EQ(file.at(begin), 0x07);
      const std::size_t entries = (u64(begin + 11) & 0xFFFFFFFFULL) / 16;
      std::vector<std::uint64_t> times;
      for (std::size_t e = 0; e < entries; ++e) times.push_back(u64(begin + 15 + 16 * e));
      EXPECT_FALSE(times.empty());
      EXPECT_TRUE(std::is_sorted(times.begin(), times.end())) << "chunk " << chunk << " channel " << channel;
    }
  }
}

TEST(McapWriterTest, AFileWithoutMessagesIsWhole) {
  std::vector<std::uint8_t> file;
  Writer writer([&](std::span<const std::uint8_t> b) { file.insert(file.end(), b.begin(), b.end()); });
  const WriterStats stats = writer.finish();
  EXPECT_EQ(stats.messages, 0U);
  EXPECT_EQ(stats.chunks, 0U);
  const Reader reader(memory_source(file), "empty.mcap");
  EXPECT_EQ(reader.info().messages, 0U);
  EXPECT_TRUE(reader.info().channels.empty());
  EXPECT_TRUE(reader.messages({}).empty());
}

TEST(McapWriterTest, DamageIsFoundByTheCrcs) {
  const Written w = two_channels(20);
  const Reader whole(memory_source(w.file), "whole.mcap");
  // A byte of the first chunk's compressed records: the data section's CRC no longer matches.
  std::vector<std::uint8_t> chunk_hit = w.file;
  chunk_hit[whole.info().chunks[0].records_offset + 5] ^= 0x20;
  EXPECT_NE(open_error(chunk_hit).find("data section CRC mismatch"), std::string::npos) << open_error(chunk_hit);
  // A byte of the summary (the last chunk index's uncompressed size): the summary CRC.
  std::vector<std::uint8_t> summary_hit = w.file;
  summary_hit[summary_hit.size() - 8 - 29 - 4 * 26 - 1] ^= 0x01;  // before the 4 summary offsets, footer, magic
  EXPECT_NE(open_error(summary_hit).find("summary CRC mismatch"), std::string::npos) << open_error(summary_hit);
}

TEST(McapWriterTest, RefusesWhatWouldMakeABadFile) {
  std::vector<std::uint8_t> file;
  Writer writer([&](std::span<const std::uint8_t> b) { file.insert(file.end(), b.begin(), b.end()); });
  EXPECT_THROW(writer.add_channel(1, "/x", "cdr"), Error);  // no schema 1 yet
  const auto s = writer.add_schema("x", "ros2msg", "");
  const auto c = writer.add_channel(s, "/x", "cdr");
  EXPECT_THROW(writer.write(static_cast<std::uint16_t>(c + 1), 0, std::string_view("x")), Error);
  (void)writer.finish();
  EXPECT_THROW(writer.write(c, 0, std::string_view("x")), Error);
  EXPECT_THROW((void)writer.finish(), Error);
}

}  // namespace
}  // namespace hmap::ros::mcap
