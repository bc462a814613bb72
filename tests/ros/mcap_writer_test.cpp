// The MCAP writer (src/hmap/ros/mcap_writer.hpp) read back by our reader: every record it writes,
// the chunks' and sections' CRCs checked, the summary's indexes used; damage found by the CRCs.

#include "hmap/ros/mcap_writer.hpp"

#include <gtest/gtest.h>

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
