#include "hmap/ros/rosbag_scan.hpp"

#include <bzlib.h>
#include <roslz4/lz4s.h>

#include <algorithm>
#include <optional>
#include <utility>

namespace hmap::ros::access {

namespace {

constexpr std::string_view kMagic = "#ROSBAG V2.0\n";

// Record ops (Bags/Format/2.0).
constexpr char kMessageData = 0x02;
constexpr char kBagHeader = 0x03;
constexpr char kIndexData = 0x04;
constexpr char kChunk = 0x05;
constexpr char kChunkInfo = 0x06;
constexpr char kConnection = 0x07;

std::uint32_t u32(const char* p) {
  const auto* b = reinterpret_cast<const unsigned char*>(p);
  return static_cast<std::uint32_t>(b[0]) | static_cast<std::uint32_t>(b[1]) << 8 | static_cast<std::uint32_t>(b[2]) << 16 |
         static_cast<std::uint32_t>(b[3]) << 24;
}

std::uint64_t u64(const char* p) { return static_cast<std::uint64_t>(u32(p)) | static_cast<std::uint64_t>(u32(p + 4)) << 32; }

/// The name=value fields of a record header (or of a connection record's body), or nullopt when
/// they do not fill it exactly: each is a 4-byte length, then name=value within that length.
std::optional<std::vector<std::pair<std::string_view, std::string_view>>> parse_fields(std::string_view header) {
  std::vector<std::pair<std::string_view, std::string_view>> fields;
  std::size_t at = 0;
  while (at < header.size()) {
    if (header.size() - at < 4) return std::nullopt;
    const std::uint32_t length = u32(header.data() + at);
    if (length > header.size() - at - 4) return std::nullopt;
    const std::string_view field = header.substr(at + 4, length);
    const std::size_t eq = field.find('=');
    if (eq == std::string_view::npos) return std::nullopt;
    fields.emplace_back(field.substr(0, eq), field.substr(eq + 1));
    at += 4 + length;
  }
  return fields;
}

std::optional<std::string_view> field(const std::vector<std::pair<std::string_view, std::string_view>>& fields,
                                      std::string_view name) {
  for (const auto& [n, v] : fields) {
    if (n == name) return v;
  }
  return std::nullopt;
}

/// One record: its header fields and its data, both inside the bytes given.
struct Record {
  std::vector<std::pair<std::string_view, std::string_view>> fields;
  char op = 0;
  std::uint64_t data_at = 0;   ///< relative to the bytes given
  std::uint32_t data_length = 0;
  std::uint64_t end = 0;       ///< the next record starts here
};

enum class ReadResult { kOk, kCutOff, kMalformed };

/// The record at `at` of `bytes`; kCutOff when its lengths run past the end of `bytes`.
ReadResult read_record(std::string_view bytes, std::uint64_t at, Record& r) {
  const std::uint64_t left = bytes.size() - at;
  if (left < 4) return ReadResult::kCutOff;
  const std::uint32_t header_length = u32(bytes.data() + at);
  if (header_length > left - 4 || left - 4 - header_length < 4) return ReadResult::kCutOff;
  r.data_length = u32(bytes.data() + at + 4 + header_length);
  r.data_at = at + 8 + header_length;
  if (r.data_length > bytes.size() - r.data_at) return ReadResult::kCutOff;
  r.end = r.data_at + r.data_length;
  auto fields = parse_fields(bytes.substr(at + 4, header_length));
  if (!fields) return ReadResult::kMalformed;
  r.fields = std::move(*fields);
  const auto op = field(r.fields, "op");
  if (!op || op->size() != 1) return ReadResult::kMalformed;
  r.op = (*op)[0];
  return ReadResult::kOk;
}

class Scanner {
 public:
  explicit Scanner(std::string_view file) : file_(file) { scan_.file_size = file.size(); }

  BagScan run() {
    if (file_.substr(0, kMagic.size()) != kMagic) {
      scan_.stop = "not a ROS 1 bag v2.0 (no \"#ROSBAG V2.0\" line)";
      return std::move(scan_);
    }
    std::uint64_t at = kMagic.size();
    while (at < file_.size()) {
      Record r;
      const ReadResult result = read_record(file_, at, r);
      if (result == ReadResult::kCutOff) {
        // A chunk cut off: its messages stored as they are (no compression) up to the cut are whole.
        Record head;
        if (uncompressed_chunk_head(at, head)) {
          ++scan_.chunk_count;
          scan_.compressions.insert("none");
          const std::uint64_t inner_end = walk_chunk(file_, head.data_at, file_.size(), kTopLevel);
          return stopped(inner_end, inner_end < file_.size() ? "a record cut off inside a chunk" : "a chunk cut off");
        }
        return stopped(at, what_is_cut(at) + " cut off");
      }
      if (result == ReadResult::kMalformed) return stopped(at, "a malformed record");
      if (!top_level(r, at)) return std::move(scan_);
      at = r.end;
    }
    scan_.end = at;
    return std::move(scan_);
  }

 private:
  BagScan stopped(std::uint64_t at, std::string why) {
    stop_at(at, std::move(why));
    return std::move(scan_);
  }
  void stop_at(std::uint64_t at, std::string why) {
    scan_.end = at;
    scan_.stop = std::move(why);
  }

  /// What the record cut off at `at` is, as far as its header tells.
  std::string what_is_cut(std::uint64_t at) const {
    const std::uint64_t left = file_.size() - at;
    if (left >= 4 && u32(file_.data() + at) <= left - 4) {
      const auto fields = parse_fields(file_.substr(at + 4, u32(file_.data() + at)));
      const auto op = fields ? field(*fields, "op") : std::nullopt;
      if (op && op->size() == 1) {
        switch ((*op)[0]) {
          case kBagHeader: return "the file header record";
          case kChunk: return "a chunk";
          case kIndexData: return "an index data record";
          case kChunkInfo: return "a chunk info record";
          case kConnection: return "a connection record";
          case kMessageData: return "a message record";
          default: break;
        }
      }
    }
    return at == kMagic.size() ? "the file header record" : "a record";
  }

  /// Whether `at` starts an uncompressed chunk's header (whole; its data may be cut off).
  bool uncompressed_chunk_head(std::uint64_t at, Record& head) const {
    const std::uint64_t left = file_.size() - at;
    if (left < 8) return false;
    const std::uint32_t header_length = u32(file_.data() + at);
    if (header_length > left - 8) return false;
    const auto fields = parse_fields(file_.substr(at + 4, header_length));
    if (!fields) return false;
    const auto op = field(*fields, "op");
    const auto compression = field(*fields, "compression");
    if (!op || *op != std::string_view(&kChunk, 1) || !compression || *compression != "none") return false;
    head.data_at = at + 8 + header_length;
    return true;
  }

  /// Reads one top-level record; false (with scan_.stop set) to stop there.
  bool top_level(const Record& r, std::uint64_t at) {
    switch (r.op) {
      case kBagHeader: {
        const auto index_pos = field(r.fields, "index_pos");
        if (index_pos && index_pos->size() == 8) scan_.index_pos = u64(index_pos->data());
        scan_.has_header = true;
        return true;
      }
      case kIndexData:
      case kChunkInfo:
        return true;  // the index: not needed to read on
      case kConnection:
      case kMessageData:
        // At the top level in bags of format 1.2, and in one whose recorder was killed while it
        // wrote an uncompressed chunk (the chunk's header still says 0 bytes).
        if (!inner(file_, r, kTopLevel)) {
          stop_at(at, "a malformed record");
          return false;
        }
        return true;
      case kChunk:
        return chunk(r, at);
      default:
        stop_at(at, "a record of unknown op " + std::to_string(static_cast<unsigned char>(r.op)));
        return false;
    }
  }

  bool chunk(const Record& r, std::uint64_t at) {
    const auto compression = field(r.fields, "compression");
    const auto size_field = field(r.fields, "size");
    if (!compression || !size_field || size_field->size() != 4) {
      stop_at(at, "a malformed chunk header");
      return false;
    }
    const std::uint32_t size = u32(size_field->data());
    const std::string kind(*compression);
    if (kind == "none") {
      if (size != r.data_length) {
        stop_at(at, "an uncompressed chunk whose size is not its length");
        return false;
      }
      ++scan_.chunk_count;
      scan_.compressions.insert(kind);
      const std::uint64_t inner_end = walk_chunk(file_, r.data_at, r.end, kTopLevel);
      if (inner_end != r.end) {
        stop_at(inner_end, "a malformed record inside a chunk");
        return false;
      }
      return true;
    }
    if (kind != "bz2" && kind != "lz4") {
      stop_at(at, "a chunk of unknown compression " + kind);
      return false;
    }
    std::string data;
    if (size == 0 && r.data_length == 0) {
      // The chunk a recorder was writing when it was killed: its sizes are written when it closes.
      stop_at(at, "an unfinished " + kind + " chunk, its header still saying 0 bytes");
      return false;
    }
    if (!decompress_chunk(kind, file_.substr(r.data_at, r.data_length), size, data)) {
      stop_at(at, "a chunk (" + kind + ") that does not decompress to its stated size");
      return false;
    }
    // A compressed chunk is read whole or not at all: its messages are taken back when a record
    // inside it is malformed.
    const std::size_t messages_before = scan_.messages.size();
    const auto chunk_index = static_cast<std::uint32_t>(scan_.chunks.size());
    if (walk_chunk(data, 0, data.size(), chunk_index) != data.size()) {
      scan_.messages.resize(messages_before);
      stop_at(at, "a chunk (" + kind + ") with a malformed record inside");
      return false;
    }
    scan_.chunks.push_back({kind, r.data_at, r.data_length, size});
    ++scan_.chunk_count;
    scan_.compressions.insert(kind);
    return true;
  }

  /// Reads the connection and message records of a chunk's data [begin, end) of `bytes`; returns
  /// where it stopped (end when every record was whole and well formed).
  std::uint64_t walk_chunk(std::string_view bytes, std::uint64_t begin, std::uint64_t end, std::uint32_t chunk) {
    const std::string_view part = bytes.substr(0, end);
    std::uint64_t at = begin;
    while (at < end) {
      Record r;
      if (read_record(part, at, r) != ReadResult::kOk) return at;
      if (r.op != kConnection && r.op != kMessageData) return at;
      if (!inner(part, r, chunk)) return at;
      at = r.end;
    }
    return at;
  }

  /// A connection or message data record; false when it is malformed.
  bool inner(std::string_view bytes, const Record& r, std::uint32_t chunk) {
    const auto conn = field(r.fields, "conn");
    if (!conn || conn->size() != 4) return false;
    const std::uint32_t id = u32(conn->data());
    if (r.op == kConnection) {
      const auto topic = field(r.fields, "topic");
      const auto body = parse_fields(bytes.substr(r.data_at, r.data_length));
      if (!topic || !body) return false;
      const auto type = field(*body, "type");
      const auto md5 = field(*body, "md5sum");
      if (!type || !md5) return false;
      // A connection appears in every chunk that uses it and again in the index: the first wins.
      scan_.connections.emplace(id, ScannedConnection{std::string(*topic), std::string(*type), std::string(*md5)});
      return true;
    }
    const auto time = field(r.fields, "time");
    if (!time || time->size() != 8 || scan_.connections.count(id) == 0) return false;
    const std::uint64_t sec = u32(time->data());
    const std::uint64_t nsec = u32(time->data() + 4);
    scan_.messages.push_back({id, sec * 1000000000ULL + nsec, chunk, r.data_at, r.data_length});
    return true;
  }

  std::string_view file_;
  BagScan scan_;
};

/// Runs a streaming decompressor: `step(out, capacity, produced)` writes up to `capacity` bytes
/// at `out`, says how many, and returns 1 at the end of the stream, 0 to go on, -1 on an error.
template <typename Step>
bool run_decompressor(std::string_view in, std::uint32_t size, std::string& out, Step step) {
  // Start from a few times the input and grow with the output: a damaged size costs nothing.
  out.assign(std::min<std::uint64_t>(size, 4 * static_cast<std::uint64_t>(in.size()) + 65536), '\0');
  std::size_t have = 0;
  for (int guard = 0; guard < 1 << 20; ++guard) {
    if (have == out.size()) {
      if (out.size() == size) {
        // Full: the stream must end here, with not one more byte.
        char extra = 0;
        std::size_t produced = 0;
        const int r = step(&extra, 1, produced);
        out.resize(have);
        return r == 1 && produced == 0;
      }
      out.resize(std::min<std::uint64_t>(size, 2 * static_cast<std::uint64_t>(out.size())));
    }
    std::size_t produced = 0;
    const int r = step(out.data() + have, out.size() - have, produced);
    have += produced;
    if (r < 0) return false;
    if (r == 1) {
      out.resize(have);
      return have == size;
    }
  }
  return false;
}

}  // namespace

BagScan scan_bag(std::string_view bytes) { return Scanner(bytes).run(); }

bool decompress_chunk(const std::string& compression, std::string_view in, std::uint32_t size, std::string& out) {
  if (compression == "bz2") {
    bz_stream s{};
    if (BZ2_bzDecompressInit(&s, 0, 0) != BZ_OK) return false;
    s.next_in = const_cast<char*>(in.data());
    s.avail_in = static_cast<unsigned>(in.size());
    const bool ok = run_decompressor(in, size, out, [&](char* o, std::size_t capacity, std::size_t& produced) {
      s.next_out = o;
      s.avail_out = static_cast<unsigned>(capacity);
      const unsigned in_before = s.avail_in;
      const int r = BZ2_bzDecompress(&s);
      produced = capacity - s.avail_out;
      if (r == BZ_OK && produced == 0 && s.avail_in == in_before) return -1;  // the input ended early
      return r == BZ_STREAM_END ? 1 : r == BZ_OK ? 0 : -1;
    });
    BZ2_bzDecompressEnd(&s);
    return ok;
  }
  if (compression == "lz4") {
    roslz4_stream s{};
    if (roslz4_decompressStart(&s) != ROSLZ4_OK) return false;
    s.input_next = const_cast<char*>(in.data());
    s.input_left = static_cast<int>(in.size());
    const bool ok = run_decompressor(in, size, out, [&](char* o, std::size_t capacity, std::size_t& produced) {
      s.output_next = o;
      s.output_left = static_cast<int>(std::min<std::size_t>(capacity, 1U << 30));
      const int before = s.output_left;
      const int in_before = s.input_left;
      const int r = roslz4_decompress(&s);
      produced = static_cast<std::size_t>(before - s.output_left);
      if (r == ROSLZ4_OK && produced == 0 && s.input_left == in_before) return -1;  // the input ended early
      return r == ROSLZ4_STREAM_END ? 1 : r == ROSLZ4_OK ? 0 : -1;
    });
    roslz4_decompressEnd(&s);
    return ok;
  }
  return false;
}

std::vector<std::uint8_t> ScannedMessages::bytes(std::size_t k) const {
  const ScannedMessage& m = scan_.messages.at(k);
  std::lock_guard<std::mutex> lock(mutex_);
  std::string_view from = file_;
  if (m.chunk != kTopLevel) {
    if (cached_chunk_ != m.chunk) {
      const ScannedChunk& c = scan_.chunks.at(m.chunk);
      cached_chunk_ = kTopLevel;
      // It decompressed while the bag was scanned: the same bytes give the same result.
      if (!decompress_chunk(c.compression, from.substr(c.data_at, c.data_length), c.size, cached_)) return {};
      cached_chunk_ = m.chunk;
    }
    from = cached_;
  }
  const auto* p = reinterpret_cast<const std::uint8_t*>(from.data() + m.offset);
  return std::vector<std::uint8_t>(p, p + m.length);
}

}  // namespace hmap::ros::access
