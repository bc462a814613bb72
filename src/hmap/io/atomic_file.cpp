#include "hmap/io/atomic_file.hpp"

#include <fcntl.h>
#include <fnmatch.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cctype>
#include <chrono>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <random>
#include <streambuf>
#include <string>
#include <vector>

#include "hmap/core/error.hpp"

namespace hmap {

namespace {

/// An output streambuf onto a POSIX file descriptor, so that the same fd can be fsynced.
/// Remembers the errno of the first failed write.
class FdStreambuf : public std::streambuf {
 public:
  explicit FdStreambuf(int fd) : fd_(fd) { setp(buffer_.data(), buffer_.data() + buffer_.size()); }

  [[nodiscard]] int error() const { return error_; }

 protected:
  int_type overflow(int_type ch) override {
    if (!flush_buffer()) return traits_type::eof();
    if (!traits_type::eq_int_type(ch, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(ch);
      pbump(1);
    }
    return traits_type::not_eof(ch);
  }

  int sync() override { return flush_buffer() ? 0 : -1; }

  std::streamsize xsputn(const char* data, std::streamsize count) override {
    // Large blocks bypass the buffer.
    if (count >= static_cast<std::streamsize>(buffer_.size())) {
      if (!flush_buffer() || !write_all(data, static_cast<std::size_t>(count))) return 0;
      return count;
    }
    return std::streambuf::xsputn(data, count);
  }

 private:
  bool flush_buffer() {
    const auto pending = static_cast<std::size_t>(pptr() - pbase());
    if (pending > 0 && !write_all(pbase(), pending)) return false;
    setp(buffer_.data(), buffer_.data() + buffer_.size());
    return true;
  }

  bool write_all(const char* data, std::size_t count) {
    if (error_ != 0) return false;
    while (count > 0) {
      const ssize_t n = ::write(fd_, data, count);
      if (n < 0) {
        if (errno == EINTR) continue;
        error_ = errno;
        return false;
      }
      data += n;
      count -= static_cast<std::size_t>(n);
    }
    return true;
  }

  int fd_;
  int error_ = 0;
  std::array<char, std::size_t{1} << 16> buffer_{};
};

std::filesystem::path temporary_path_for(const std::filesystem::path& path) {
  std::random_device device;
  char suffix[32];
  std::snprintf(suffix, sizeof suffix, "%08x", static_cast<unsigned>(device()));
  std::string name(1, '.');  // appended piecewise: `"." + std::string` trips a false -Wrestrict in GCC 12
  name.append(path.filename().string()).append(".tmp.").append(std::to_string(::getpid()));
  name.append(1, '.').append(suffix);
  return path.parent_path() / name;
}

/// The PID in `name` when it is `.NAME.tmp.PID.XXXXXXXX` (temporary_path_for's pattern) for
/// `target_name`, else 0.
pid_t temporary_owner(const std::string& name, const std::string& target_name) {
  const std::string prefix = "." + target_name + ".tmp.";
  if (!name.starts_with(prefix)) return 0;
  const std::size_t dot = name.find('.', prefix.size());
  if (dot == std::string::npos || dot == prefix.size() || dot - prefix.size() > 9 || name.size() != dot + 9) return 0;
  long pid = 0;
  for (std::size_t k = prefix.size(); k < dot; ++k) {
    if (!std::isdigit(static_cast<unsigned char>(name[k]))) return 0;
    pid = pid * 10 + (name[k] - '0');
  }
  for (std::size_t k = dot + 1; k < name.size(); ++k) {
    if (!std::isxdigit(static_cast<unsigned char>(name[k]))) return 0;
  }
  return static_cast<pid_t>(pid);
}

[[noreturn]] void fail(const std::filesystem::path& path, const std::string& what, int error) {
  throw Error(path.string() + ": " + what + ": " + std::strerror(error));
}

/// Makes the rename durable; a failure here does not undo the write, so it is not reported.
void sync_directory(const std::filesystem::path& dir) {
  const int fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

/// What a file that is not a regular one is, for messages.
std::string not_regular(mode_t mode) {
  const char* what = S_ISDIR(mode)    ? "a folder"
                     : S_ISCHR(mode)  ? "a character device"
                     : S_ISBLK(mode)  ? "a block device"
                     : S_ISFIFO(mode) ? "a FIFO"
                     : S_ISSOCK(mode) ? "a socket"
                                      : "not a regular file";
  return std::string("is ") + what + ", not a regular file: refusing to replace it";
}

}  // namespace

void check_output_file(const std::filesystem::path& path) {
  if (path.filename().empty()) throw Error(path.string() + ": not a file name");
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) throw Error(path.string() + ": " + not_regular(st.st_mode));
  check_output_folder(path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path(), path);
}

void check_output_folder(const std::filesystem::path& dir, const std::filesystem::path& for_path) {
  const std::string name = (for_path.empty() ? dir : for_path).string();
  struct stat st {};
  if (::stat(dir.c_str(), &st) != 0) {
    throw Error(name + ": the output folder " + dir.string() + " does not exist (" + std::strerror(errno) + ")");
  }
  if (!S_ISDIR(st.st_mode)) throw Error(name + ": " + dir.string() + " is not a folder");
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    throw Error(name + ": cannot write in the output folder " + dir.string() + " (" + std::strerror(errno) + ")");
  }
}

namespace {

/// Writes `writer`'s bytes to a new temporary file beside `path`, fsyncs and closes it, and
/// returns its name; `path` itself is not touched. On failure nothing is left behind.
std::filesystem::path write_temporary(const std::filesystem::path& path, const std::function<void(std::ostream&)>& writer) {
  if (path.filename().empty()) throw Error(path.string() + ": not a file name");
  remove_stale_temporaries(path);
  const std::filesystem::path temporary = temporary_path_for(path);

  // New files get 0666 minus the umask, as with std::ofstream; a replaced file keeps its mode.
  struct stat existing {};
  const bool replacing = ::stat(path.c_str(), &existing) == 0;
  // rename() would replace a device, a FIFO or a socket with a regular file (`--out /dev/null`
  // as root replaced the device node).
  if (replacing && !S_ISREG(existing.st_mode)) throw Error(path.string() + ": " + not_regular(existing.st_mode));
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) fail(path, "cannot create temporary file " + temporary.string(), errno);
  if (replacing) ::fchmod(fd, existing.st_mode & 07777);

  bool fd_open = true;
  try {
    FdStreambuf buffer(fd);
    std::ostream out(&buffer);
    // A writer that gives up (OctoMap's "could not serialise") says why when a write failed: a
    // full disk reads "No space left on device".
    const auto cause = [&buffer] { return buffer.error() != 0 ? std::string(": ") + std::strerror(buffer.error()) : std::string(); };
    try {
      writer(out);
    } catch (const Error& e) {
      throw Error(path.string() + ": " + e.what() + cause());
    } catch (const std::exception& e) {
      throw Error(path.string() + ": cannot write: " + e.what() + cause());
    }
    out.flush();
    if (!out) fail(path, "cannot write", buffer.error() != 0 ? buffer.error() : EIO);
    if (::fsync(fd) != 0) fail(path, "cannot fsync", errno);
    fd_open = false;
    if (::close(fd) != 0) fail(path, "cannot close", errno);
  } catch (...) {
    if (fd_open) ::close(fd);
    ::unlink(temporary.c_str());
    throw;
  }
  return temporary;
}

std::function<void(std::ostream&)> bytes_writer(std::string_view bytes) {
  return [bytes](std::ostream& out) { out.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); };
}

/// The folder an output path names, absolute and without a trailing separator (`out/` and
/// `out/.` are `out`), so that its parent and name are those of the folder itself.
std::filesystem::path folder_path(const std::filesystem::path& out) {
  std::filesystem::path p = std::filesystem::absolute(out).lexically_normal();
  if (p.filename().empty() && p.has_parent_path() && p != p.root_path()) p = p.parent_path();
  if (p == p.root_path() || p.filename().empty() || p.filename() == "..") {
    throw Error(out.string() + ": cannot be replaced as an output folder; give a folder of its own");
  }
  return p;
}

}  // namespace

void write_file_atomic(const std::filesystem::path& path, const std::function<void(std::ostream&)>& writer) {
  const std::filesystem::path temporary = write_temporary(path, writer);
  if (::rename(temporary.c_str(), path.c_str()) != 0) {
    const int error = errno;
    ::unlink(temporary.c_str());
    fail(path, "cannot rename into place", error);
  }
  sync_directory(path.parent_path());
}

void write_files_with_record(std::initializer_list<std::pair<std::filesystem::path, std::string_view>> files,
                             const std::filesystem::path& record, std::string_view record_bytes) {
  std::vector<std::pair<std::filesystem::path, std::filesystem::path>> pending;  // temporary, target
  const auto discard = [&pending] {
    for (const auto& [temporary, target] : pending) ::unlink(temporary.c_str());
  };
  try {
    for (const auto& [path, bytes] : files) pending.emplace_back(write_temporary(path, bytes_writer(bytes)), path);
    pending.emplace_back(write_temporary(record, bytes_writer(record_bytes)), record);
  } catch (...) {
    discard();
    throw;
  }
  // Commit: the old record goes first (durably), the record comes back last.
  if (::unlink(record.c_str()) != 0 && errno != ENOENT) {
    const int error = errno;
    discard();
    fail(record, "cannot remove the old file", error);
  }
  sync_directory(record.parent_path());
  for (std::size_t i = 0; i < pending.size(); ++i) {
    if (i + 1 == pending.size()) {
      // Every file durably in place before the record appears, even across a power loss.
      for (const auto& [path, bytes] : files) sync_directory(path.parent_path());
    }
    const auto& [temporary, target] = pending[i];
    if (::rename(temporary.c_str(), target.c_str()) != 0) {
      const int error = errno;
      for (std::size_t j = i; j < pending.size(); ++j) ::unlink(pending[j].first.c_str());
      fail(target, "cannot rename into place", error);
    }
  }
  sync_directory(record.parent_path());
}

void remove_stale_temporaries(const std::filesystem::path& target_in) {
  const std::filesystem::path target = target_in.filename().empty() ? target_in.parent_path() : target_in;
  const std::string target_name = target.filename().string();
  if (target_name.empty()) return;
  const std::filesystem::path dir = target.parent_path().empty() ? std::filesystem::path(".") : target.parent_path();
  std::error_code error;
  std::filesystem::directory_iterator it(dir, error);
  if (error) return;
  const auto now = std::chrono::system_clock::now();
  for (; it != std::filesystem::directory_iterator(); it.increment(error)) {
    if (error) return;
    const std::filesystem::path path = it->path();
    const pid_t owner = temporary_owner(path.filename().string(), target_name);
    if (owner <= 0 || owner == ::getpid()) continue;
    if (::kill(owner, 0) == 0 || errno != ESRCH) continue;  // its writer runs (or is not ours to ask)
    struct stat st {};
    if (::lstat(path.c_str(), &st) != 0 || S_ISLNK(st.st_mode)) continue;
    const auto modified = std::chrono::system_clock::from_time_t(st.st_mtime);
    if (now - modified < kStaleTemporaryAge) continue;
    std::error_code ignored;
    std::filesystem::remove_all(path, ignored);
  }
}

std::filesystem::path make_staging_folder(const std::filesystem::path& target) {
  const std::filesystem::path name = target.filename().empty() ? target.parent_path() : target;
  remove_stale_temporaries(name);
  for (int attempt = 0; attempt < 8; ++attempt) {
    const std::filesystem::path staging = temporary_path_for(name);
    if (::mkdir(staging.c_str(), 0777) == 0) return staging;
    if (errno != EEXIST) fail(name, "cannot create the staging folder " + staging.string(), errno);
  }
  fail(name, "cannot create a staging folder", EEXIST);
}

void replace_folder_atomic(const std::filesystem::path& staging, const std::filesystem::path& target_in) {
  const std::filesystem::path target = target_in.filename().empty() ? target_in.parent_path() : target_in;
  struct stat st {};
  const bool exists = ::lstat(target.c_str(), &st) == 0;
  if (exists && !S_ISDIR(st.st_mode)) throw Error(target.string() + ": " + not_regular(st.st_mode));
  if (!exists) {
    if (::rename(staging.c_str(), target.c_str()) != 0) fail(target, "cannot rename the new folder into place", errno);
  } else {
    if (::renameat2(AT_FDCWD, staging.c_str(), AT_FDCWD, target.c_str(), RENAME_EXCHANGE) != 0) {
      fail(target, "cannot exchange the new folder with the old one", errno);
    }
    std::error_code ignored;  // the old set, now at `staging`: a failure here leaves it hidden, not wrong
    std::filesystem::remove_all(staging, ignored);
  }
  sync_directory(target.parent_path());
}

void check_output_set_folder(const std::filesystem::path& out_in, std::initializer_list<std::string_view> owned,
                             std::string_view command) {
  const std::filesystem::path out = folder_path(out_in);
  struct stat st {};
  if (::lstat(out.c_str(), &st) != 0) {
    check_output_folder(out.parent_path(), out_in);
    return;
  }
  if (!S_ISDIR(st.st_mode)) throw Error(out_in.string() + ": the output folder is not a folder");
  check_output_folder(out.parent_path(), out_in);
  for (const auto& entry : std::filesystem::directory_iterator(out)) {
    const std::string name = entry.path().filename().string();
    const bool folder = entry.is_directory() && !entry.is_symlink();
    bool ours = false;
    for (std::string_view pattern : owned) {
      const bool names_folder = pattern.ends_with('/');
      if (names_folder) pattern.remove_suffix(1);
      if (::fnmatch(std::string(pattern).c_str(), name.c_str(), FNM_PERIOD) != 0) continue;
      ours = names_folder ? folder : entry.is_regular_file() && !entry.is_symlink();
      break;
    }
    if (!ours) {
      throw Error(out_in.string() + ": holds '" + name + "', which hmap " + std::string(command) +
                  " does not write; the folder is replaced as a whole, so give a new one");
    }
  }
}

void write_folder_atomic(const std::filesystem::path& out_in, const std::function<void(const std::filesystem::path& dir)>& writer) {
  const std::filesystem::path out = folder_path(out_in);
  const std::filesystem::path staging = make_staging_folder(out);
  try {
    writer(staging);
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove_all(staging, ignored);
    throw;
  }
  replace_folder_atomic(staging, out);
}

void write_file_atomic(const std::filesystem::path& path, std::string_view bytes) { write_file_atomic(path, bytes_writer(bytes)); }

}  // namespace hmap
