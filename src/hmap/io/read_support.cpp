#include "hmap/io/read_support.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>

#include "hmap/core/error.hpp"

namespace hmap::detail {

namespace {

/// Closes a POSIX file descriptor on every path out of a scope.
class FdCloser {
 public:
  explicit FdCloser(int fd) : fd_(fd) {}
  ~FdCloser() { ::close(fd_); }
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

std::string read_file_bytes(const std::filesystem::path& path, std::size_t max_bytes) {
  const bool standard_input = path == "-";
  const std::string name = standard_input ? std::string("standard input") : path.string();
  // O_NONBLOCK: opening a FIFO for reading otherwise waits for a writer, forever. It is refused
  // below by its type; regular files ignore the flag.
  const int fd = standard_input ? ::dup(STDIN_FILENO) : ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw InputError(name, "", std::string("cannot open: ") + std::strerror(errno));
  const FdCloser closer(fd);

  struct stat info {};
  if (::fstat(fd, &info) != 0) throw InputError(name, "", std::string("cannot open: ") + std::strerror(errno));
  const bool regular = S_ISREG(info.st_mode);
  // Regular files only: a device (/dev/zero) or a pipe (`<(yes ...)`) has no size to check and
  // may never end. Standard input ("-") may be a pipe, read up to the limit.
  if (!regular && !(standard_input && !S_ISDIR(info.st_mode))) {
    throw InputError(name, "", "cannot open: " + std::string(file_kind(info.st_mode)) +
                                   ", not a regular file");
  }
  if (regular && static_cast<std::uintmax_t>(info.st_size) > max_bytes) {
    throw InputError(name, "", std::to_string(info.st_size) + " bytes, more than the " + std::to_string(max_bytes >> 20) +
                                   " MiB an input may hold");
  }
  if (standard_input) {
    const int flags = ::fcntl(fd, F_GETFL);
    if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  }
  // A regular file is read in one go (its real size, not a claim); standard input grows the
  // buffer as data arrives, up to the limit.
  std::string bytes;
  bytes.resize(regular ? static_cast<std::size_t>(info.st_size) : std::size_t{1} << 16);
  std::size_t filled = 0;
  for (;;) {
    if (filled == bytes.size()) {
      if (regular) break;
      if (bytes.size() > max_bytes) {
        throw InputError(name, "", "more than the " + std::to_string(max_bytes >> 20) + " MiB an input may hold");
      }
      bytes.resize(std::min(bytes.size() * 2, max_bytes + 1));
    }
    const ssize_t n = ::read(fd, bytes.data() + filled, bytes.size() - filled);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw InputError(name, "", std::string("cannot read: ") + std::strerror(errno));
    }
    if (n == 0) break;
    filled += static_cast<std::size_t>(n);
  }
  bytes.resize(filled);  // the file may have shrunk between fstat and read
  return bytes;
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
