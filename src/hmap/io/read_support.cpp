#include "hmap/io/read_support.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

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

[[noreturn]] void throw_cannot_open(const std::filesystem::path& path, int error) {
  throw InputError(path.string(), "", std::string("cannot open: ") + std::strerror(error));
}

}  // namespace

std::string read_file_bytes(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw_cannot_open(path, errno);
  const FdCloser closer(fd);

  struct stat info {};
  if (::fstat(fd, &info) != 0) throw_cannot_open(path, errno);
  if (S_ISDIR(info.st_mode)) throw_cannot_open(path, EISDIR);

  // A regular file is read in one go; a pipe or device grows the buffer as data arrives.
  std::string bytes;
  const bool regular = S_ISREG(info.st_mode);
  bytes.resize(regular ? static_cast<std::size_t>(info.st_size) : std::size_t{1} << 16);
  std::size_t filled = 0;
  for (;;) {
    if (filled == bytes.size()) {
      if (regular) break;
      bytes.resize(bytes.size() * 2);
    }
    const ssize_t n = ::read(fd, bytes.data() + filled, bytes.size() - filled);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw_cannot_open(path, errno);
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
