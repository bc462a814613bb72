#include "hmap/io/read_support.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <memory>

#include "hmap/core/error.hpp"

namespace hmap::detail {

namespace {

/// Closes a POSIX file descriptor on every path out of a scope.
class FdCloser {
 public:
  explicit FdCloser(int fd) : fd_(fd) {}
  ~FdCloser() {
    if (fd_ >= 0) ::close(fd_);
  }
  void release() { fd_ = -1; }
  FdCloser(const FdCloser&) = delete;
  FdCloser& operator=(const FdCloser&) = delete;

 private:
  int fd_;
};

}  // namespace

std::string_view file_kind(unsigned mode) {
  if (S_ISREG(mode)) return "a regular file";
  if (S_ISDIR(mode)) return "a folder";
  if (S_ISFIFO(mode)) return "a pipe or FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

namespace {

/// An input opened as read_file_bytes and read_file_records take it: regular files and standard
/// input only, within `max_bytes` by its size; a FIFO never blocks in open().
struct OpenedInput {
  int fd = -1;
  bool regular = false;
  std::size_t size = 0;  // fstat's, for a regular file
  std::string name;
};

OpenedInput open_input(const std::filesystem::path& path, std::size_t max_bytes) {
  OpenedInput in;
  const bool standard_input = path == "-";
  in.name = standard_input ? std::string("standard input") : path.string();
  // O_NONBLOCK: opening a FIFO for reading otherwise waits for a writer, forever. It is refused
  // below by its type; regular files ignore the flag.
  in.fd = standard_input ? ::dup(STDIN_FILENO) : ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (in.fd < 0) throw InputError(in.name, "", std::string("cannot open: ") + std::strerror(errno));
  FdCloser on_error(in.fd);
  struct stat info {};
  if (::fstat(in.fd, &info) != 0) throw InputError(in.name, "", std::string("cannot open: ") + std::strerror(errno));
  in.regular = S_ISREG(info.st_mode);
  // Regular files only: a device (/dev/zero) or a pipe (`<(yes ...)`) has no size to check and
  // may never end. Standard input ("-") may be a pipe, read up to the limit.
  if (!in.regular && !(standard_input && !S_ISDIR(info.st_mode))) {
    throw InputError(in.name, "", "cannot open: " + std::string(file_kind(info.st_mode)) +
                                      ", not a regular file");
  }
  if (in.regular && static_cast<std::uintmax_t>(info.st_size) > max_bytes) {
    throw InputError(in.name, "", std::to_string(info.st_size) + " bytes, more than the " +
                                      std::to_string(max_bytes >> 20) + " MiB an input may hold");
  }
  in.size = in.regular ? static_cast<std::size_t>(info.st_size) : 0;
  if (standard_input) {
    const int flags = ::fcntl(in.fd, F_GETFL);
    if (flags >= 0) ::fcntl(in.fd, F_SETFL, flags & ~O_NONBLOCK);
  }
  on_error.release();
  return in;
}

/// read() until `count` bytes or the end; the bytes read. Throws InputError naming the input.
std::size_t read_some(const OpenedInput& in, char* into, std::size_t count) {
  std::size_t filled = 0;
  while (filled < count) {
    const ssize_t n = ::read(in.fd, into + filled, count - filled);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw InputError(in.name, "", std::string("cannot read: ") + std::strerror(errno));
    }
    if (n == 0) break;
    filled += static_cast<std::size_t>(n);
  }
  return filled;
}

}  // namespace

std::string read_file_bytes(const std::filesystem::path& path, std::size_t max_bytes) {
  const OpenedInput in = open_input(path, max_bytes);
  const FdCloser closer(in.fd);
  // A regular file is read in one go (its real size, not a claim); standard input grows the
  // buffer as data arrives, up to the limit.
  std::string bytes;
  bytes.resize(in.regular ? in.size : std::size_t{1} << 16);
  std::size_t filled = 0;
  for (;;) {
    if (filled == bytes.size()) {
      if (in.regular) break;
      if (bytes.size() > max_bytes) {
        throw InputError(in.name, "", "more than the " + std::to_string(max_bytes >> 20) + " MiB an input may hold");
      }
      bytes.resize(std::min(bytes.size() * 2, max_bytes + 1));
    }
    const std::size_t n = read_some(in, bytes.data() + filled, bytes.size() - filled);
    if (n == 0) break;
    filled += n;
  }
  bytes.resize(filled);  // the file may have shrunk between fstat and read
  return bytes;
}

std::size_t read_file_records(const std::filesystem::path& path, std::size_t record_bytes,
                              const std::function<void(std::span<const char>)>& consume, std::size_t max_bytes,
                              std::size_t* size_hint) {
  if (record_bytes == 0 || record_bytes > kChunkBytes) throw Error("read_file_records: record size out of range");
  const OpenedInput in = open_input(path, max_bytes);
  const FdCloser closer(in.fd);
  if (size_hint != nullptr) *size_hint = in.size;
  // A buffer of whole records, refilled: the file's bytes pass through the cache once, and no
  // buffer the size of the file is allocated (and zero-filled) per file.
  const std::size_t capacity = kChunkBytes - kChunkBytes % record_bytes;
  const std::unique_ptr<char[]> buffer(new char[capacity]);
  std::size_t total = 0;
  std::size_t held = 0;  // bytes of an incomplete record carried over
  for (;;) {
    const std::size_t n = read_some(in, buffer.get() + held, capacity - held);
    total += n;
    if (total > max_bytes) {
      throw InputError(in.name, "", "more than the " + std::to_string(max_bytes >> 20) + " MiB an input may hold");
    }
    held += n;
    const std::size_t whole = held - held % record_bytes;
    if (whole > 0) consume({buffer.get(), whole});
    std::memmove(buffer.get(), buffer.get() + whole, held - whole);
    held -= whole;
    if (n == 0) break;
  }
  return total;
}

bool parse_double(std::string_view token, double& value) {
  // from_chars rejects a leading '+', which text writers do emit.
  if (token.size() > 1 && token.front() == '+' && token[1] != '-' && token[1] != '+') {
    token.remove_prefix(1);
  }
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  return ec == std::errc() && ptr == end && !token.empty();
}

bool parse_uint(std::string_view token, std::uint64_t& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  return ec == std::errc() && ptr == end && !token.empty();
}

void split_whitespace(std::string_view line, std::vector<std::string_view>& tokens) {
  tokens.clear();
  std::size_t i = 0;
  const std::size_t n = line.size();
  while (i < n) {
    while (i < n && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < n && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
}

bool LineReader::next(std::string_view& line) {
  if (offset_ >= text_.size()) return false;
  const std::size_t newline = text_.find('\n', offset_);
  const std::size_t end = newline == std::string_view::npos ? text_.size() : newline;
  line = text_.substr(offset_, end - offset_);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  offset_ = newline == std::string_view::npos ? text_.size() : newline + 1;
  ++next_line_number_;
  return true;
}

std::string quoted(std::string_view token) {
  constexpr std::size_t kMax = 40;
  // Built by appending: `"'" + std::string(...)` trips a false -Wrestrict in GCC 12.
  std::string text(1, '\'');
  text.append(token.substr(0, kMax));
  if (token.size() > kMax) text.append("...");
  text.push_back('\'');
  return text;
}

}  // namespace hmap::detail
