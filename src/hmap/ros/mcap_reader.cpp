#include "hmap/ros/mcap_reader.hpp"

#include <fcntl.h>
#include <lz4frame.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "hmap/core/error.hpp"

namespace hmap::ros::mcap {

namespace fs = std::filesystem;

namespace {

constexpr std::uint64_t kRecordPrefix = 9;        // opcode + u64 length
constexpr std::uint64_t kFooterContent = 20;      // summary_start, summary_offset_start, summary_crc
constexpr std::uint64_t kMessageFixed = 22;       // channel, sequence, log time, publish time
/// The most a chunk may claim to hold. A chunk is a few MB in practice; this stops a damaged size
/// field from asking for more memory than a recording can mean.
constexpr std::uint64_t kMaxChunkBytes = std::uint64_t{4} << 30;

std::string at_byte(std::uint64_t offset) { return "byte " + std::to_string(offset); }

/// Little-endian fields of one record's content, every read checked against the content's end.
class Cursor {
 public:
  Cursor(std::span<const std::uint8_t> bytes, std::uint64_t base, const std::string& name, const char* what)
      : bytes_(bytes), base_(base), name_(name), what_(what) {}

  template <typename T>
  T get() {
    need(sizeof(T));
    T v = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i) v = static_cast<T>(v | static_cast<T>(static_cast<T>(bytes_[pos_ + i]) << (8 * i)));
    pos_ += sizeof(T);
    return v;
  }
  std::string string() {
    const auto n = get<std::uint32_t>();
    need(n);
    std::string s(reinterpret_cast<const char*>(bytes_.data() + pos_), n);
    pos_ += n;
    return s;
  }
  /// A u32- (or u64-) length-prefixed byte run, as a view.
  std::span<const std::uint8_t> bytes32() { return take(get<std::uint32_t>()); }
  std::span<const std::uint8_t> bytes64() { return take(get<std::uint64_t>()); }
  std::span<const std::uint8_t> take(std::uint64_t n) {
    need(n);
    auto s = bytes_.subspan(pos_, static_cast<std::size_t>(n));
    pos_ += static_cast<std::size_t>(n);
    return s;
  }
  [[nodiscard]] std::uint64_t offset() const { return base_ + pos_; }
  [[nodiscard]] std::size_t pos() const { return pos_; }
  [[nodiscard]] std::size_t left() const { return bytes_.size() - pos_; }

 private:
  void need(std::uint64_t n) const {
    if (n > bytes_.size() - pos_) {
      throw InputError(name_, at_byte(base_ + pos_), std::string(what_) + ": a field of " + std::to_string(n) +
                                                         " bytes runs past the record's end");
    }
  }
  std::span<const std::uint8_t> bytes_;
  std::uint64_t base_;
  std::size_t pos_ = 0;
  const std::string& name_;
  const char* what_;
};

class FileSource final : public ByteSource {
 public:
  explicit FileSource(const fs::path& path) : fd_(::open(path.c_str(), O_RDONLY | O_CLOEXEC)) {
    if (fd_ < 0) throw InputError(path.string(), "", std::string("cannot open: ") + std::strerror(errno));
    struct stat st{};
    if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
      ::close(fd_);
      throw InputError(path.string(), "", "cannot open: not a regular file");
    }
    size_ = static_cast<std::uint64_t>(st.st_size);
    name_ = path.string();
  }
  ~FileSource() override { ::close(fd_); }
  FileSource(const FileSource&) = delete;
  FileSource& operator=(const FileSource&) = delete;
  [[nodiscard]] std::uint64_t size() const override { return size_; }
  void read(std::uint64_t offset, std::span<std::uint8_t> out) const override {
    std::size_t done = 0;
    while (done < out.size()) {
      const ssize_t n = ::pread(fd_, out.data() + done, out.size() - done, static_cast<off_t>(offset + done));
      if (n <= 0) throw InputError(name_, at_byte(offset + done), n == 0 ? "file shrank while read" : std::strerror(errno));
      done += static_cast<std::size_t>(n);
    }
  }

 private:
  int fd_;
  std::uint64_t size_ = 0;
  std::string name_;
};

class MemorySource final : public ByteSource {
 public:
  explicit MemorySource(std::span<const std::uint8_t> bytes) : bytes_(bytes.begin(), bytes.end()) {}
  [[nodiscard]] std::uint64_t size() const override { return bytes_.size(); }
  void read(std::uint64_t offset, std::span<std::uint8_t> out) const override {
    if (out.empty()) return;  // memcpy from or to a null pointer is undefined even for 0 bytes
    std::memcpy(out.data(), bytes_.data() + offset, out.size());
  }

 private:
  std::vector<std::uint8_t> bytes_;
};

std::vector<std::uint8_t> read_bytes(const ByteSource& src, std::uint64_t offset, std::uint64_t n) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(n));
  src.read(offset, out);
  return out;
}

std::uint64_t le64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

/// CRC-32 (the MCAP spec's: zlib's polynomial) of file bytes [begin, end), read in blocks.
std::uint32_t file_crc(const ByteSource& src, std::uint64_t begin, std::uint64_t end) {
  uLong crc = crc32_z(0L, Z_NULL, 0);
  std::vector<std::uint8_t> block(std::size_t{1} << 20);
  for (std::uint64_t at = begin; at < end;) {
    const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(block.size(), end - at));
    src.read(at, std::span(block.data(), n));
    crc = crc32_z(crc, block.data(), n);
    at += n;
  }
  return static_cast<std::uint32_t>(crc);
}

struct RecordHead {
  std::uint8_t opcode = 0;
  std::uint64_t length = 0;
};

RecordHead read_head(const ByteSource& src, std::uint64_t at) {
  std::uint8_t h[kRecordPrefix];
  src.read(at, h);
  return {h[0], le64(h + 1)};
}

/// A Schema record's id, name and encoding (its data, the message definition, is not needed).
void add_schema(Cursor& c, Info& info) {
  Schema s;
  s.id = c.get<std::uint16_t>();
  s.name = c.string();
  s.encoding = c.string();
  info.schemas.emplace(s.id, s);
}

/// A Channel record's id, schema, topic and message encoding (its metadata is not needed).
void add_channel(Cursor& c, Info& info) {
  Channel ch;
  ch.id = c.get<std::uint16_t>();
  ch.schema_id = c.get<std::uint16_t>();
  ch.topic = c.string();
  ch.message_encoding = c.string();
  info.channels.emplace(ch.id, ch);
}

/// The fixed part of a Chunk record up to its records, and where they start.
ChunkInfo parse_chunk(const ByteSource& src, std::uint64_t at, std::uint64_t length, const std::string& name) {
  // Fields: start time, end time, uncompressed size, uncompressed crc, compression, records length.
  const std::uint64_t head_max = std::min<std::uint64_t>(length, 28 + 4 + 255 + 8);
  const auto head = read_bytes(src, at + kRecordPrefix, head_max);
  Cursor c(head, at + kRecordPrefix, name, "chunk");
  ChunkInfo chunk;
  chunk.start_time = chunk.index_start_time = c.get<std::uint64_t>();
  chunk.end_time = chunk.index_end_time = c.get<std::uint64_t>();
  chunk.record_offset = at;
  chunk.uncompressed_size = c.get<std::uint64_t>();
  chunk.uncompressed_crc = c.get<std::uint32_t>();
  chunk.compression = c.string();
  chunk.compressed_size = c.get<std::uint64_t>();
  chunk.records_offset = c.offset();
  if (chunk.compressed_size > length - c.pos()) {
    throw InputError(name, at_byte(at), "chunk records of " + std::to_string(chunk.compressed_size) +
                                            " bytes run past the chunk's end");
  }
  if (chunk.compression != "" && chunk.compression != "zstd" && chunk.compression != "lz4") {
    throw InputError(name, at_byte(at), "chunk compression \"" + chunk.compression + "\" is not one hmap reads (none, zstd, lz4)");
  }
  return chunk;
}

}  // namespace

std::shared_ptr<const ByteSource> file_source(const fs::path& path) { return std::make_shared<FileSource>(path); }

std::shared_ptr<const ByteSource> memory_source(std::span<const std::uint8_t> bytes) {
  return std::make_shared<MemorySource>(bytes);
}

std::vector<std::uint8_t> decompress_chunk(std::span<const std::uint8_t> data, const std::string& compression,
                                           std::uint64_t uncompressed_size, std::uint32_t crc, const std::string& name,
                                           const std::string& position) {
  if (uncompressed_size > kMaxChunkBytes) {
    throw InputError(name, position, "chunk claims " + std::to_string(uncompressed_size) + " uncompressed bytes, more than a chunk holds");
  }
  std::vector<std::uint8_t> out;
  if (compression.empty()) {
    if (data.size() != uncompressed_size) throw InputError(name, position, "uncompressed chunk whose size is not its length");
    out.assign(data.begin(), data.end());
  } else {
    // Grown as the data decompresses (not sized from the claim), so a damaged size field cannot
    // make us allocate more than the compressed bytes really hold.
    const std::size_t limit = static_cast<std::size_t>(uncompressed_size);
    // Started at four times the compressed size and doubled: sized at 64 times, a 1 MB chunk of
    // point clouds zero-filled 64 MB before it was cut back (9 % of `hmap map` on an MCAP).
    out.resize(std::min<std::size_t>(limit, 4 * data.size() + 65536));
    std::size_t produced = 0;
    const auto grow = [&] {
      if (out.size() < limit) out.resize(std::min<std::size_t>(limit, out.size() * 2));
    };
    if (compression == "zstd") {
      std::unique_ptr<ZSTD_DStream, decltype(&ZSTD_freeDStream)> z(ZSTD_createDStream(), ZSTD_freeDStream);
      ZSTD_inBuffer in{data.data(), data.size(), 0};
      std::size_t ret = 1;
      while (true) {
        ZSTD_outBuffer o{out.data(), out.size(), produced};
        ret = ZSTD_decompressStream(z.get(), &o, &in);
        produced = o.pos;
        if (ZSTD_isError(ret)) throw InputError(name, position, std::string("zstd chunk: ") + ZSTD_getErrorName(ret));
        if (ret == 0 && in.pos == in.size) break;
        if (produced == out.size()) {
          if (out.size() >= limit) break;  // more data than claimed: caught below
          grow();
        } else if (in.pos == in.size) {
          break;  // input consumed, frame not finished: caught below
        }
      }
      if (ret != 0 || in.pos != in.size) throw InputError(name, position, "zstd chunk is cut off or holds more than its stated size");
    } else if (compression == "lz4") {
      LZ4F_dctx* ctx = nullptr;
      if (LZ4F_isError(LZ4F_createDecompressionContext(&ctx, LZ4F_VERSION))) throw Error("lz4: cannot create a context");
      std::unique_ptr<LZ4F_dctx, decltype(&LZ4F_freeDecompressionContext)> guard(ctx, LZ4F_freeDecompressionContext);
      std::size_t consumed = 0;
      std::size_t ret = 1;
      while (consumed < data.size() && ret != 0) {
        if (produced == out.size()) {
          if (out.size() >= limit) break;
          grow();
        }
        std::size_t dst = out.size() - produced;
        std::size_t src = data.size() - consumed;
        ret = LZ4F_decompress(ctx, out.data() + produced, &dst, data.data() + consumed, &src, nullptr);
        if (LZ4F_isError(ret)) throw InputError(name, position, std::string("lz4 chunk: ") + LZ4F_getErrorName(ret));
        produced += dst;
        consumed += src;
        if (dst == 0 && src == 0) break;
      }
      if (ret != 0 || consumed != data.size()) throw InputError(name, position, "lz4 chunk is cut off or holds more than its stated size");
    } else {
      throw InputError(name, position, "chunk compression \"" + compression + "\" is not one hmap reads (none, zstd, lz4)");
    }
    if (produced != uncompressed_size) {
      throw InputError(name, position, "chunk decompresses to " + std::to_string(produced) + " bytes, its record says " +
                                           std::to_string(uncompressed_size));
    }
    out.resize(produced);
  }
  if (crc != 0) {
    const auto got = static_cast<std::uint32_t>(crc32_z(crc32_z(0L, Z_NULL, 0), out.data(), out.size()));
    if (got != crc) throw InputError(name, position, "chunk CRC mismatch (the chunk is damaged)");
  }
  return out;
}

Reader::Reader(std::shared_ptr<const ByteSource> source, std::string name) : source_(std::move(source)), name_(std::move(name)) {
  const ByteSource& src = *source_;
  const std::uint64_t size = src.size();
  std::uint8_t magic[8] = {};
  if (size >= 8) src.read(0, magic);
  if (size < 8 || std::memcmp(magic, kMagic, 8) != 0) {
    throw InputError(name_, at_byte(0), "not an MCAP file (no MCAP magic)");
  }
  if (size < 8 + kRecordPrefix) throw InputError(name_, at_byte(8), "cut off before its header record");
  const RecordHead header = read_head(src, 8);
  if (header.opcode != kHeader) throw InputError(name_, at_byte(8), "the first record is not a header");
  if (header.length > size - 8 - kRecordPrefix) throw InputError(name_, at_byte(8), "header record runs past the end of the file");
  const std::uint64_t data_start = 8 + kRecordPrefix + header.length;

  // The footer and the trailing magic, when the file was finished.
  const std::uint64_t footer_at = size >= data_start + kRecordPrefix + kFooterContent + 8 ? size - 8 - kRecordPrefix - kFooterContent : 0;
  std::uint64_t summary_start = 0;
  std::uint64_t summary_offset_start = 0;
  bool finished = false;
  if (footer_at != 0) {
    const auto tail = read_bytes(src, footer_at, kRecordPrefix + kFooterContent + 8);
    finished = tail[0] == kFooter && le64(tail.data() + 1) == kFooterContent &&
               std::memcmp(tail.data() + kRecordPrefix + kFooterContent, kMagic, 8) == 0;
    if (finished) {
      summary_start = le64(tail.data() + kRecordPrefix);
      summary_offset_start = le64(tail.data() + kRecordPrefix + 8);
      std::uint32_t summary_crc = 0;
      for (int i = 3; i >= 0; --i) summary_crc = (summary_crc << 8) | tail[kRecordPrefix + 16 + static_cast<std::size_t>(i)];
      if (summary_start != 0) {
        if (summary_start < data_start || summary_start > footer_at) {
          throw InputError(name_, at_byte(footer_at), "footer points its summary to byte " + std::to_string(summary_start) +
                                                          ", outside the file's records");
        }
        if (summary_offset_start != 0 && (summary_offset_start < summary_start || summary_offset_start > footer_at)) {
          throw InputError(name_, at_byte(footer_at), "footer's summary offset section lies outside the file's records");
        }
        // The summary CRC covers the summary (and summary offset) section and the footer up to its CRC field.
        if (summary_crc != 0 && file_crc(src, summary_start, footer_at + kRecordPrefix + 16) != summary_crc) {
          throw InputError(name_, at_byte(summary_start), "summary CRC mismatch (the summary section is damaged)");
        }
      }
    }
  }
  if (finished && summary_start != 0) {
    read_summary(summary_start, summary_offset_start != 0 ? summary_offset_start : footer_at);
    // The Data End record (13 bytes) closes the data section just before the summary.
    if (summary_start >= data_start + 13) {
      const auto end = read_bytes(src, summary_start - 13, 13);
      if (end[0] == kDataEnd && le64(end.data() + 1) == 4) {
        const std::uint32_t crc = static_cast<std::uint32_t>(end[9]) | static_cast<std::uint32_t>(end[10]) << 8 |
                                  static_cast<std::uint32_t>(end[11]) << 16 | static_cast<std::uint32_t>(end[12]) << 24;
        if (crc != 0 && file_crc(src, 0, summary_start - 13) != crc) {
          throw InputError(name_, at_byte(summary_start - 13), "data section CRC mismatch (the recording is damaged)");
        }
        data_crc_checked_ = crc != 0;
      }
    }
  }
  if (!info_.indexed) {
    info_ = Info{};  // what a summary without chunk indexes gave is counted again by the scan
    scan_data_section();
  }
}

void Reader::read_summary(std::uint64_t begin, std::uint64_t end) {
  const ByteSource& src = *source_;
  std::size_t chunk_count = 0;
  bool statistics = false;
  for (std::uint64_t at = begin; at < end;) {
    if (end - at < kRecordPrefix) throw InputError(name_, at_byte(at), "summary record cut off");
    const RecordHead head = read_head(src, at);
    if (head.length > end - at - kRecordPrefix) throw InputError(name_, at_byte(at), "summary record runs past the summary's end");
    const std::uint64_t content_at = at + kRecordPrefix;
    if (head.opcode == kSchema || head.opcode == kChannel || head.opcode == kStatistics || head.opcode == kChunkIndex) {
      const auto content = read_bytes(src, content_at, head.length);
      Cursor c(content, content_at, name_, "summary record");
      if (head.opcode == kSchema) {
        add_schema(c, info_);
      } else if (head.opcode == kChannel) {
        add_channel(c, info_);
      } else if (head.opcode == kStatistics) {
        statistics = true;
        info_.messages = c.get<std::uint64_t>();
        (void)c.get<std::uint16_t>();
        (void)c.get<std::uint32_t>();
        (void)c.get<std::uint32_t>();
        (void)c.get<std::uint32_t>();
        chunk_count = c.get<std::uint32_t>();
        info_.start_time = c.get<std::uint64_t>();
        info_.end_time = c.get<std::uint64_t>();
        auto counts = c.bytes32();
        if (counts.size() % 10 != 0) throw InputError(name_, at_byte(at), "statistics: channel counts of a length not a multiple of 10");
        Cursor m(counts, 0, name_, "statistics");
        while (m.left() > 0) {
          const auto id = m.get<std::uint16_t>();
          info_.message_counts[id] = m.get<std::uint64_t>();
        }
      } else {
        const auto index_start_time = c.get<std::uint64_t>();
        const auto index_end_time = c.get<std::uint64_t>();
        const auto chunk_at = c.get<std::uint64_t>();
        const auto chunk_length = c.get<std::uint64_t>();
        auto offsets = c.bytes32();
        if (offsets.size() % 10 != 0) throw InputError(name_, at_byte(at), "chunk index: message index offsets of a bad length");
        if (chunk_at < 8 || chunk_at > src.size() || chunk_length > src.size() - chunk_at || chunk_length < kRecordPrefix) {
          throw InputError(name_, at_byte(at), "chunk index points outside the file");
        }
        const RecordHead chunk_head = read_head(src, chunk_at);
        if (chunk_head.opcode != kChunk || chunk_head.length != chunk_length - kRecordPrefix) {
          throw InputError(name_, at_byte(at), "chunk index points to byte " + std::to_string(chunk_at) + ", where no chunk starts");
        }
        ChunkInfo chunk = parse_chunk(src, chunk_at, chunk_head.length, name_);
        chunk.index_start_time = index_start_time;
        chunk.index_end_time = index_end_time;
        Cursor m(offsets, 0, name_, "chunk index");
        while (m.left() > 0) {
          const auto channel = m.get<std::uint16_t>();
          const auto index_at = m.get<std::uint64_t>();
          chunk.channels.insert(channel);
          // A Message Index record follows its chunk; one pointing elsewhere is not used.
          if (index_at >= chunk_at + chunk_length && index_at <= src.size() - kRecordPrefix) {
            chunk.message_indexes[channel] = index_at;
          }
        }
        info_.chunks.push_back(std::move(chunk));
      }
    }
    at = content_at + head.length;
  }
  for (const auto& [id, ch] : info_.channels) {
    if (ch.schema_id != 0 && info_.schemas.count(ch.schema_id) == 0) {
      throw InputError(name_, "channel " + ch.topic, "names schema " + std::to_string(ch.schema_id) + ", which the file lacks");
    }
  }
  // Indexed reading needs the counts and every chunk's index; otherwise the data section is scanned.
  info_.indexed = statistics && chunk_count > 0 && chunk_count == info_.chunks.size();
}

void Reader::scan_data_section() {
  const ByteSource& src = *source_;
  const std::uint64_t size = src.size();
  std::uint64_t at = 8 + kRecordPrefix + read_head(src, 8).length;
  bool ended = false;
  while (at < size) {
    if (size - at < kRecordPrefix) break;
    const RecordHead head = read_head(src, at);
    if (head.length > size - at - kRecordPrefix) break;  // cut off inside this record
    const std::uint64_t content_at = at + kRecordPrefix;
    if (head.opcode == kDataEnd || head.opcode == kFooter) {
      if (head.opcode == kDataEnd && head.length >= 4) {
        const auto crc_bytes = read_bytes(src, content_at, 4);
        const std::uint32_t crc = static_cast<std::uint32_t>(crc_bytes[0]) | static_cast<std::uint32_t>(crc_bytes[1]) << 8 |
                                  static_cast<std::uint32_t>(crc_bytes[2]) << 16 | static_cast<std::uint32_t>(crc_bytes[3]) << 24;
        if (crc != 0 && file_crc(src, 0, at) != crc) {
          throw InputError(name_, at_byte(at), "data section CRC mismatch (the recording is damaged)");
        }
        data_crc_checked_ = crc != 0;
      }
      ended = true;
      break;
    }
    if (head.opcode == kChunk) {
      info_.chunks.push_back(parse_chunk(src, at, head.length, name_));
      walk_chunk(info_.chunks.size() - 1, nullptr, &scanned_);
    } else if (head.opcode == kSchema || head.opcode == kChannel || head.opcode == kMessage) {
      const auto content = read_bytes(src, content_at, head.length);
      Cursor c(content, content_at, name_, "record");
      if (head.opcode == kSchema) {
        add_schema(c, info_);
      } else if (head.opcode == kChannel) {
        add_channel(c, info_);
      } else {
        MessageRef ref;
        ref.channel = c.get<std::uint16_t>();
        (void)c.get<std::uint32_t>();
        ref.log_time = c.get<std::uint64_t>();
        (void)c.get<std::uint64_t>();
        ref.offset = c.offset();
        ref.length = c.left();
        scanned_.push_back(ref);
      }
    }
    at = content_at + head.length;
  }
  if (!ended) {
    info_.warnings.push_back(name_ + ": the recording is cut off at byte " + std::to_string(at) +
                             " (no data end or footer: its writer was stopped); read the " + std::to_string(scanned_.size()) +
                             " whole messages before it");
  }
  for (const auto& ref : scanned_) {
    if (info_.channels.count(ref.channel) == 0) {
      throw InputError(name_, "message at log time " + std::to_string(ref.log_time),
                       "names channel " + std::to_string(ref.channel) + ", which the file does not define");
    }
    ++info_.message_counts[ref.channel];
    info_.start_time = info_.messages == 0 ? ref.log_time : std::min(info_.start_time, ref.log_time);
    info_.end_time = std::max(info_.end_time, ref.log_time);
    ++info_.messages;
  }
}

/// std::allocator that leaves bytes uninitialised on resize: a decompression buffer is written
/// before it is read, and zero-filling it cost as much as a tenth of reading a recording.
template <typename T>
struct UninitialisedAllocator : std::allocator<T> {
  using std::allocator<T>::allocator;
  template <typename U>
  struct rebind {
    using other = UninitialisedAllocator<U>;
  };
  template <typename U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// One chunk, decompressed as far as needed so far; a zstd stream goes on from where it stopped.
struct Reader::ChunkCache {
  std::size_t chunk = MessageRef::kNoChunk;
  std::vector<std::uint8_t, UninitialisedAllocator<std::uint8_t>> compressed;
  std::vector<std::uint8_t, UninitialisedAllocator<std::uint8_t>> out;
  std::size_t produced = 0;
  std::uint64_t limit = 0;  ///< the chunk's stated uncompressed size
  bool complete = false;
  std::unique_ptr<ZSTD_DStream, decltype(&ZSTD_freeDStream)> zstd{nullptr, ZSTD_freeDStream};
  ZSTD_inBuffer in{};
  std::size_t ret = 1;  ///< ZSTD_decompressStream's last answer (0: a frame just ended)
};

Reader::~Reader() = default;
Reader::Reader(Reader&&) noexcept = default;
Reader& Reader::operator=(Reader&&) noexcept = default;

std::span<const std::uint8_t> Reader::chunk_records(std::size_t chunk, std::uint64_t needed) const {
  const ChunkInfo& c = info_.chunks.at(chunk);
  const std::string position = "chunk at " + at_byte(c.record_offset);
  if (!cache_) cache_ = std::make_unique<ChunkCache>();
  ChunkCache& k = *cache_;
  try {
    if (k.chunk != chunk) {
      k.chunk = MessageRef::kNoChunk;
      k.complete = false;
      k.produced = 0;
      k.limit = c.uncompressed_size;
      k.compressed.resize(static_cast<std::size_t>(c.compressed_size));
      source_->read(c.records_offset, std::span<std::uint8_t>(k.compressed.data(), k.compressed.size()));
      if (c.compression != "zstd" || !data_crc_checked_) {
        // Whole, with the chunk's CRC: uncompressed and lz4 chunks, and any chunk of a recording
        // whose bytes no data section CRC vouched for.
        const auto records = decompress_chunk(std::span<const std::uint8_t>(k.compressed.data(), k.compressed.size()), c.compression, c.uncompressed_size,
                                              data_crc_checked_ ? 0 : c.uncompressed_crc, name_, position);
        k.out.assign(records.begin(), records.end());
        k.produced = k.out.size();
        k.complete = true;
      } else {
        if (c.uncompressed_size > kMaxChunkBytes) {
          throw InputError(name_, position, "chunk claims " + std::to_string(c.uncompressed_size) +
                                                " uncompressed bytes, more than a chunk holds");
        }
        if (!k.zstd) k.zstd.reset(ZSTD_createDStream());
        if (!k.zstd || ZSTD_isError(ZSTD_initDStream(k.zstd.get()))) throw Error("zstd: cannot create a decompression stream");
        k.in = ZSTD_inBuffer{k.compressed.data(), k.compressed.size(), 0};
        k.ret = 1;
        k.out.clear();
      }
      k.chunk = chunk;
    }
    needed = std::min<std::uint64_t>(needed, k.limit);
    if (!k.complete && needed == k.limit && k.limit > 0) {
      // The whole chunk: in one pass into a buffer of its size (zstd then writes straight into it,
      // where the stream would go through its own window and copy out), starting over from the
      // frame's start if a smaller read began it. The size is the chunk record's, which the data
      // section's CRC vouched for; the buffer is not zero-filled, so only what zstd writes is touched.
      k.out.resize(static_cast<std::size_t>(k.limit));
      const std::size_t got = ZSTD_decompress(k.out.data(), k.out.size(), k.compressed.data(), k.compressed.size());
      if (ZSTD_isError(got)) throw InputError(name_, position, std::string("zstd chunk: ") + ZSTD_getErrorName(got));
      if (got != k.limit) {
        throw InputError(name_, position, "chunk decompresses to " + std::to_string(got) + " bytes, its record says " +
                                              std::to_string(k.limit));
      }
      k.produced = got;
      k.complete = true;
    }
    while (!k.complete && k.produced < needed + (needed == k.limit ? 1 : 0)) {
      if (k.produced == k.out.size()) {
        if (k.out.size() >= k.limit) {
          // Every stated byte is out: the frame must end without more.
          ZSTD_outBuffer o{nullptr, 0, 0};
          if (k.ret != 0) k.ret = ZSTD_decompressStream(k.zstd.get(), &o, &k.in);
          if (ZSTD_isError(k.ret) || k.ret != 0 || k.in.pos != k.in.size) {
            throw InputError(name_, position, "zstd chunk is cut off or holds more than its stated size");
          }
          k.complete = true;
          break;
        }
        // Grown as the data decompresses (a damaged size claims nothing we allocate up front): to
        // what this read needs, at least twice the last size; the whole chunk at once when four
        // times the compressed bytes reach it.
        const std::uint64_t want = std::max<std::uint64_t>({needed, 2 * k.out.size(), 65536,
                                                            needed == k.limit ? 4 * k.compressed.size() : 0});
        k.out.resize(static_cast<std::size_t>(std::min<std::uint64_t>(k.limit, want)));
      }
      ZSTD_outBuffer o{k.out.data(), k.out.size(), k.produced};
      k.ret = ZSTD_decompressStream(k.zstd.get(), &o, &k.in);
      k.produced = o.pos;
      if (ZSTD_isError(k.ret)) throw InputError(name_, position, std::string("zstd chunk: ") + ZSTD_getErrorName(k.ret));
      if (k.ret == 0 && k.in.pos == k.in.size) {
        if (k.produced != k.limit) {
          throw InputError(name_, position, "chunk decompresses to " + std::to_string(k.produced) +
                                                " bytes, its record says " + std::to_string(k.limit));
        }
        k.complete = true;
      } else if (k.produced < k.out.size() && k.in.pos == k.in.size) {
        throw InputError(name_, position, "zstd chunk is cut off or holds more than its stated size");
      }
    }
  } catch (...) {
    k.chunk = MessageRef::kNoChunk;
    throw;
  }
  return {k.out.data(), k.produced};
}

void Reader::walk_chunk(std::size_t chunk, const std::set<std::uint16_t>* channels, std::vector<MessageRef>* out) {
  const std::span<const std::uint8_t> records = chunk_records(chunk);
  const std::string where = "chunk at " + at_byte(info_.chunks[chunk].record_offset);
  for (std::size_t at = 0; at < records.size();) {
    if (records.size() - at < kRecordPrefix) throw InputError(name_, where, "record cut off inside the chunk");
    const std::uint8_t opcode = records[at];
    const std::uint64_t length = le64(records.data() + at + 1);
    if (length > records.size() - at - kRecordPrefix) throw InputError(name_, where, "record runs past the chunk's end");
    const std::size_t content_at = at + kRecordPrefix;
    Cursor c(records.subspan(content_at, static_cast<std::size_t>(length)), content_at, name_, "record in chunk");
    if (opcode == kSchema) {
      add_schema(c, info_);
    } else if (opcode == kChannel) {
      add_channel(c, info_);
    } else if (opcode == kMessage) {
      if (length < kMessageFixed) throw InputError(name_, where, "message record shorter than its fixed fields");
      MessageRef ref;
      ref.channel = c.get<std::uint16_t>();
      (void)c.get<std::uint32_t>();
      ref.log_time = c.get<std::uint64_t>();
      (void)c.get<std::uint64_t>();
      ref.chunk = chunk;
      ref.offset = content_at + kMessageFixed;
      ref.length = length - kMessageFixed;
      if (channels == nullptr || channels->count(ref.channel) > 0) out->push_back(ref);
    }
    at = content_at + static_cast<std::size_t>(length);
  }
}

std::vector<MessageRef> Reader::messages(const std::set<std::uint16_t>& channels) const {
  std::vector<MessageRef> out;
  if (!info_.indexed) {
    for (const auto& ref : scanned_) {
      if (channels.count(ref.channel) > 0) out.push_back(ref);
    }
    return out;
  }
  for (std::size_t k = 0; k < info_.chunks.size(); ++k) {
    const auto& held = info_.chunks[k].channels;
    const bool may_hold = held.empty() || std::any_of(channels.begin(), channels.end(), [&](std::uint16_t c) { return held.count(c) > 0; });
    // walk_chunk adds what it meets to info_ (schemas and channels a chunk repeats): the summary
    // has them already, so this changes nothing a caller sees.
    if (!may_hold || list_from_indexes(k, channels, &out)) continue;
    const_cast<Reader*>(this)->walk_chunk(k, &channels, &out);
  }
  return out;
}

bool Reader::list_from_indexes(std::size_t chunk, const std::set<std::uint16_t>& channels, std::vector<MessageRef>* out) const {
  const ChunkInfo& c = info_.chunks[chunk];
  const ByteSource& src = *source_;
  std::vector<MessageRef> found;
  for (const std::uint16_t channel : channels) {
    if (c.channels.count(channel) == 0) continue;
    const auto at = c.message_indexes.find(channel);
    if (at == c.message_indexes.end()) return false;
    const RecordHead head = read_head(src, at->second);
    const std::uint64_t content_at = at->second + kRecordPrefix;
    if (head.opcode != kMessageIndex || head.length > src.size() - content_at) {
      throw InputError(name_, at_byte(at->second), "the chunk index points to no message index record here");
    }
    const auto content = read_bytes(src, content_at, head.length);
    Cursor m(content, content_at, name_, "message index");
    if (m.get<std::uint16_t>() != channel) throw InputError(name_, at_byte(at->second), "message index of another channel");
    const auto records = m.bytes32();
    if (records.size() % 16 != 0) throw InputError(name_, at_byte(at->second), "message index entries of a length not a multiple of 16");
    Cursor r(records, content_at, name_, "message index");
    while (r.left() > 0) {
      MessageRef ref;
      ref.log_time = r.get<std::uint64_t>();
      ref.offset = r.get<std::uint64_t>();
      if (ref.offset >= c.uncompressed_size) throw InputError(name_, at_byte(at->second), "message index entry past its chunk's end");
      ref.channel = channel;
      ref.chunk = chunk;
      ref.length = MessageRef::kFromRecord;
      found.push_back(ref);
    }
  }
  // File order within the chunk, as walk_chunk lists them (the indexes are per channel, by time).
  std::sort(found.begin(), found.end(), [](const MessageRef& a, const MessageRef& b) { return a.offset < b.offset; });
  out->insert(out->end(), found.begin(), found.end());
  return true;
}

std::vector<std::uint8_t> Reader::read(const MessageRef& ref) const {
  if (ref.chunk == MessageRef::kNoChunk) {
    if (ref.offset > source_->size() || ref.length > source_->size() - ref.offset) {
      throw InputError(name_, at_byte(ref.offset), "message runs past the end of the file");
    }
    return read_bytes(*source_, ref.offset, ref.length);
  }
  const std::uint64_t chunk_size = info_.chunks.at(ref.chunk).uncompressed_size;
  if (ref.length == MessageRef::kFromRecord) {
    // Listed by a Message Index: the record at the offset must be a message of that channel.
    const std::string where = "chunk " + std::to_string(ref.chunk) + ", offset " + std::to_string(ref.offset);
    if (ref.offset > chunk_size || chunk_size - ref.offset < kRecordPrefix + kMessageFixed) {
      throw InputError(name_, where, "message index points past the chunk's end");
    }
    auto records = chunk_records(ref.chunk, ref.offset + kRecordPrefix + kMessageFixed);
    const std::uint8_t* head = records.data() + ref.offset;
    const std::uint64_t length = le64(head + 1);
    if (head[0] != kMessage || length < kMessageFixed || length > chunk_size - ref.offset - kRecordPrefix) {
      throw InputError(name_, where, "message index points to no whole message record");
    }
    if ((static_cast<std::uint16_t>(head[kRecordPrefix]) | static_cast<std::uint16_t>(head[kRecordPrefix + 1]) << 8) != ref.channel) {
      throw InputError(name_, where, "message index points to a message of another channel");
    }
    records = chunk_records(ref.chunk, ref.offset + kRecordPrefix + length);
    const auto* begin = records.data() + ref.offset + kRecordPrefix + kMessageFixed;
    return {begin, begin + (length - kMessageFixed)};
  }
  if (ref.offset > chunk_size || ref.length > chunk_size - ref.offset) {
    throw InputError(name_, "chunk " + std::to_string(ref.chunk), "message runs past the chunk's end");
  }
  const auto records = chunk_records(ref.chunk, ref.offset + ref.length);
  const auto* begin = records.data() + ref.offset;
  return {begin, begin + ref.length};
}

}  // namespace hmap::ros::mcap
