#pragma once
// Shared by the fuzz targets of fuzz/: the input as a file (the readers take paths), and the
// checks every target makes on what a reader returns or throws.
//
// Each target source defines its entry point as HMAP_FUZZ_ENTRY(data, size). Built with libFuzzer
// (HMAP_FUZZ=ON) the entry point is LLVMFuzzerTestOneInput; in an ordinary build all targets are
// linked into one `fuzz_replay` program that feeds them the files of fuzz/corpus and
// fuzz/regressions (see replay_main.cpp), so every crash ever found stays a test.

#include <sys/mman.h>
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

#include "hmap/core/error.hpp"
#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"

#ifndef HMAP_FUZZ_NAME
#error "HMAP_FUZZ_NAME (the target's name) must be defined by the build"
#endif
#ifdef HMAP_FUZZ_LIBFUZZER
#define HMAP_FUZZ_ENTRY extern "C" int LLVMFuzzerTestOneInput
#else
#define HMAP_FUZZ_CONCAT2(a, b) a##b
#define HMAP_FUZZ_CONCAT(a, b) HMAP_FUZZ_CONCAT2(a, b)
#define HMAP_FUZZ_ENTRY int HMAP_FUZZ_CONCAT(hmap_fuzz_, HMAP_FUZZ_NAME)
#endif

namespace hmap::fuzz {

/// A violated property: printed, then abort() so that libFuzzer (or the replay test) reports it.
[[noreturn]] inline void fail(std::string_view what) {
  std::fprintf(stderr, "hmap fuzz property violated: %.*s\n", static_cast<int>(what.size()), what.data());
  std::abort();
}

/// The input bytes as a file: one memfd per process, rewritten for every input, opened by the
/// readers through /proc/self/fd/N (nothing touches the disk).
class InputFile {
 public:
  InputFile() : fd_(::memfd_create("hmap_fuzz_input", MFD_CLOEXEC)) {
    if (fd_ < 0) fail("memfd_create failed");
    path_ = "/proc/self/fd/" + std::to_string(fd_);
  }
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;
  ~InputFile() { ::close(fd_); }

  /// Replaces the file's content by `size` bytes at `data`; returns its path.
  const std::filesystem::path& write(const std::uint8_t* data, std::size_t size) {
    if (::ftruncate(fd_, 0) != 0) fail("ftruncate failed");
    std::size_t done = 0;
    while (done < size) {
      const ssize_t n = ::pwrite(fd_, data + done, size - done, static_cast<off_t>(done));
      if (n <= 0) fail("pwrite failed");
      done += static_cast<std::size_t>(n);
    }
    return path_;
  }

 private:
  int fd_;
  std::filesystem::path path_;
};

/// The process's one input file (a function-local static: libFuzzer calls the entry point
/// millions of times).
inline InputFile& input_file() {
  static InputFile file;
  return file;
}

/// What every refusal must be: one line of printable text (the CLI prints what() as it is).
inline void check_message(const hmap::Error& e) {
  const std::string_view what = e.what();
  if (what.empty()) fail("empty error message");
  for (const char c : what) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u == 0x7F) fail(std::string("error message with a control character: ") + e.what());
  }
}

/// What every cloud reader promises: finite points only, and counts that add up.
inline void check_cloud(const PointCloud& cloud, const CloudReadStats& stats) {
  for (const auto& p : cloud) {
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z())) fail("non-finite point returned");
  }
  if (stats.points_read < stats.non_finite_dropped || stats.points_read - stats.non_finite_dropped != cloud.size()) {
    fail("points_read - non_finite_dropped != points returned");
  }
}

/// Runs `read(path)` on the input; only hmap::InputError (one line) may come out of it. Any other
/// exception escapes, and libFuzzer reports it as a crash.
template <typename Read>
void read_input(const std::uint8_t* data, std::size_t size, Read read) {
  const auto& path = input_file().write(data, size);
  try {
    read(path);
  } catch (const hmap::InputError& e) {
    check_message(e);
  }
}

}  // namespace hmap::fuzz
