// The MCAP reader (src/hmap/ros/mcap_reader.hpp) on hand-built files: records, chunks (none, zstd,
// lz4), CRCs, the summary, cut-off files, and lengths that lie.

#include <gtest/gtest.h>

#include <lz4frame.h>
#include <zlib.h>
#include <zstd.h>

#include <functional>
#include <random>

#include "hmap/core/error.hpp"
#include "hmap/ros/mcap_reader.hpp"

namespace hmap {
namespace mcap_reader_test {

using Bytes = std::vector<std::uint8_t>;
namespace mcap = ros::mcap;

void put_le(Bytes& b, std::uint64_t v, int n) {
  for (int i = 0; i < n; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void put_str(Bytes& b, const std::string& s) {
  put_le(b, s.size(), 4);
  b.insert(b.end(), s.begin(), s.end());
}
Bytes record(std::uint8_t op, const Bytes& content) {
  Bytes r{op};
  put_le(r, content.size(), 8);
  r.insert(r.end(), content.begin(), content.end());
  return r;
}
Bytes schema(std::uint16_t id) {
  Bytes c;
  put_le(c, id, 2);
  put_str(c, "sensor_msgs/msg/PointCloud2");
  put_str(c, "ros2msg");
  put_str(c, "");
  return record(0x03, c);
}
Bytes channel(std::uint16_t id, const std::string& topic) {
  Bytes c;
  put_le(c, id, 2);
  put_le(c, 1, 2);
  put_str(c, topic);
  put_str(c, "cdr");
  put_le(c, 0, 4);  // metadata map
  return record(0x04, c);
}
Bytes message(std::uint16_t ch, std::uint64_t t, const Bytes& data) {
  Bytes c;
  put_le(c, ch, 2);
  put_le(c, 0, 4);
  put_le(c, t, 8);
  put_le(c, t, 8);
  c.insert(c.end(), data.begin(), data.end());
  return record(0x05, c);
}
std::uint32_t crc_of(const Bytes& b) { return static_cast<std::uint32_t>(crc32_z(0, b.data(), b.size())); }
Bytes chunk(const Bytes& records, const std::string& compression, std::uint32_t crc) {
  Bytes data = records;
  if (compression == "zstd") {
    data.resize(ZSTD_compressBound(records.size()));
    data.resize(ZSTD_compress(data.data(), data.size(), records.data(), records.size(), 3));
  } else if (compression == "lz4") {
    data.resize(LZ4F_compressFrameBound(records.size(), nullptr));
    data.resize(LZ4F_compressFrame(data.data(), data.size(), records.data(), records.size(), nullptr));
  }
  Bytes c;
  put_le(c, 0, 8);
  put_le(c, 0, 8);
  put_le(c, records.size(), 8);
  put_le(c, crc, 4);
  put_str(c, compression);
  put_le(c, data.size(), 8);
  c.insert(c.end(), data.begin(), data.end());
  return record(0x06, c);
}
Bytes start() {
  Bytes b(mcap::kMagic, mcap::kMagic + 8);
  Bytes h;
  put_str(h, "ros2");
  put_str(h, "hmap test");
  const Bytes r = record(0x01, h);
  b.insert(b.end(), r.begin(), r.end());
  return b;
}
void append(Bytes& b, const Bytes& r) { b.insert(b.end(), r.begin(), r.end()); }
/// Data end (with the data section's CRC), footer without summary, magic.
void finish(Bytes& b, bool with_crc = true) {
  Bytes d;
  put_le(d, with_crc ? crc_of(b) : 0, 4);
  append(b, record(0x0F, d));
  Bytes f;
  put_le(f, 0, 8);
  put_le(f, 0, 8);
  put_le(f, 0, 4);
  append(b, record(0x02, f));
  b.insert(b.end(), mcap::kMagic, mcap::kMagic + 8);
}

mcap::Reader open(const Bytes& b) { return mcap::Reader(mcap::memory_source(b), "t.mcap"); }

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "<no InputError>";
}

Bytes payload(std::size_t n, std::uint8_t seed) {
  Bytes p(n);
  for (std::size_t i = 0; i < n; ++i) p[i] = static_cast<std::uint8_t>(seed + i % 7);
  return p;
}

TEST(McapReaderTest, TopLevelMessagesLinearScan) {
  Bytes b = start();
  append(b, schema(1));
  append(b, channel(3, "/cloud"));
  append(b, message(3, 1000, payload(10, 1)));
  append(b, message(3, 2000, payload(5, 2)));
  finish(b);
  const auto reader = open(b);
  EXPECT_FALSE(reader.info().indexed);
  EXPECT_TRUE(reader.info().warnings.empty());
  EXPECT_EQ(reader.info().messages, 2U);
  EXPECT_EQ(reader.info().start_time, 1000U);
  EXPECT_EQ(reader.info().end_time, 2000U);
  EXPECT_EQ(reader.info().channels.at(3).topic, "/cloud");
  const auto refs = reader.messages({3});
  ASSERT_EQ(refs.size(), 2U);
  EXPECT_EQ(reader.read(refs[1]), payload(5, 2));
  EXPECT_TRUE(reader.messages({4}).empty());
}

TEST(McapReaderTest, ChunksOfEveryCompressionWithTheirCrc) {
  for (const std::string compression : {"", "zstd", "lz4"}) {
    Bytes records = schema(1);
    append(records, channel(1, "/a"));
    append(records, message(1, 5, payload(3000, 9)));
    append(records, message(1, 6, payload(17, 4)));
    Bytes b = start();
    append(b, chunk(records, compression, crc_of(records)));
    finish(b);
    const auto reader = open(b);
    ASSERT_EQ(reader.info().chunks.size(), 1U);
    EXPECT_EQ(reader.info().chunks[0].compression, compression);
    const auto refs = reader.messages({1});
    ASSERT_EQ(refs.size(), 2U) << compression;
    EXPECT_EQ(reader.read(refs[0]), payload(3000, 9));
    EXPECT_EQ(reader.read(refs[1]), payload(17, 4));
    // The chunk's CRC off by one: refused, naming the file and the chunk.
    Bytes bad = start();
    append(bad, chunk(records, compression, crc_of(records) + 1));
    finish(bad, false);
    EXPECT_NE(error_of([&] { (void)open(bad); }).find("t.mcap: chunk at byte 38: chunk CRC mismatch"), std::string::npos) << compression;
  }
}

TEST(McapReaderTest, DataSectionCrcChecked) {
  Bytes b = start();
  append(b, schema(1));
  append(b, channel(1, "/a"));
  append(b, message(1, 5, payload(30, 1)));
  finish(b);
  b[60] ^= 1;  // inside the schema record
  EXPECT_NE(error_of([&] { (void)open(b); }).find("data section CRC mismatch"), std::string::npos);
}

TEST(McapReaderTest, CutOffFileReadsItsWholeMessagesWithAWarning) {
  Bytes b = start();
  append(b, schema(1));
  append(b, channel(1, "/a"));
  for (int k = 0; k < 3; ++k) append(b, message(1, 10 + k, payload(50, static_cast<std::uint8_t>(k))));
  const std::size_t whole = b.size();
  finish(b);
  // Cut inside the third message: two whole messages.
  const Bytes cut(b.begin(), b.begin() + static_cast<std::ptrdiff_t>(whole - 20));
  const auto reader = open(cut);
  EXPECT_EQ(reader.info().messages, 2U);
  ASSERT_EQ(reader.info().warnings.size(), 1U);
  EXPECT_NE(reader.info().warnings[0].find("t.mcap: the recording is cut off at byte"), std::string::npos);
  EXPECT_NE(reader.info().warnings[0].find("read the 2 whole messages"), std::string::npos);
  // Every prefix reads or is refused; none crashes or reads past its end.
  for (std::size_t n = 0; n <= b.size(); ++n) {
    const Bytes prefix(b.begin(), b.begin() + static_cast<std::ptrdiff_t>(n));
    try {
      const auto r = open(prefix);
      for (const auto& ref : r.messages({1})) (void)r.read(ref);
    } catch (const InputError&) {
    }
  }
}

TEST(McapReaderTest, LyingLengthsAreRefusedBeforeAllocating) {
  // Not MCAP at all.
  EXPECT_NE(error_of([] { (void)open(Bytes{'#', 'R', 'O', 'S'}); }).find("not an MCAP file"), std::string::npos);
  // A channel whose topic string claims 4 GB.
  Bytes c;
  put_le(c, 1, 2);
  put_le(c, 1, 2);
  put_le(c, 0xFFFFFFF0U, 4);
  Bytes b = start();
  append(b, schema(1));
  append(b, record(0x04, c));
  finish(b);
  EXPECT_NE(error_of([&] { (void)open(b); }).find("runs past the record's end"), std::string::npos);
  // A zstd chunk claiming 2^60 bytes uncompressed.
  Bytes records = channel(1, "/a");
  Bytes z = start();
  Bytes ch = chunk(records, "zstd", 0);
  for (int i = 0; i < 8; ++i) ch[9 + 16 + static_cast<std::size_t>(i)] = i == 7 ? 0x10 : 0;
  append(z, ch);
  finish(z);
  EXPECT_NE(error_of([&] { (void)open(z); }).find("more than a chunk holds"), std::string::npos);
  // A zstd chunk whose stated size is 1 MB more than its data: refused, no 1 MB-per-claim growth.
  Bytes liar = start();
  Bytes ch2 = chunk(records, "zstd", 0);
  ch2[9 + 16 + 2] = 0x10;
  append(liar, ch2);
  finish(liar);
  EXPECT_NE(error_of([&] { (void)open(liar); }).find("decompresses to"), std::string::npos);
  // An unknown compression.
  Bytes bz = start();
  append(bz, chunk(records, "bz2", 0));
  finish(bz);
  EXPECT_NE(error_of([&] { (void)open(bz); }).find("chunk compression \"bz2\" is not one hmap reads"), std::string::npos);
  // An empty schema record (found by fuzzing: a 0-byte read from the buffer must not reach memcpy
  // with a null pointer, which UBSan reports under make test-sanitize).
  Bytes empty = start();
  append(empty, record(0x03, {}));
  finish(empty);
  EXPECT_NE(error_of([&] { (void)open(empty); }).find("runs past the record's end"), std::string::npos);
  // A message naming a channel the file lacks.
  Bytes orphan = start();
  append(orphan, message(9, 1, payload(4, 0)));
  finish(orphan);
  EXPECT_NE(error_of([&] { (void)open(orphan); }).find("names channel 9"), std::string::npos);
}

TEST(McapReaderTest, SeededDamageNeverCrashes) {
  Bytes records = schema(1);
  append(records, channel(1, "/a"));
  for (int k = 0; k < 4; ++k) append(records, message(1, static_cast<std::uint64_t>(k), payload(40, static_cast<std::uint8_t>(k))));
  Bytes b = start();
  append(b, chunk(records, "zstd", crc_of(records)));
  finish(b, false);
  std::mt19937 rng(20);
  std::uniform_int_distribution<std::size_t> position(0, b.size() - 1);
  std::uniform_int_distribution<int> value(0, 255);
  for (int trial = 0; trial < 500; ++trial) {
    Bytes d = b;
    for (int k = 0; k < 1 + trial % 3; ++k) d[position(rng)] = static_cast<std::uint8_t>(value(rng));
    try {
      const auto r = open(d);
      for (const auto& ref : r.messages({1})) (void)r.read(ref);
    } catch (const InputError&) {
    }
  }
}

}  // namespace mcap_reader_test
}  // namespace hmap
