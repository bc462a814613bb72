#pragma once
// Where the real recorded scans are: $HMAP_DATA_DIR, else the folder CMake was given
// (HMAP_DATA_DIR, default ../shared/data). Tests that need a set call HMAP_REQUIRE_DATA.

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <unistd.h>

namespace hmap::test {

inline std::filesystem::path data_dir() {
  if (const char* env = std::getenv("HMAP_DATA_DIR"); env != nullptr && *env != '\0') return env;
  return HMAP_DEFAULT_DATA_DIR;
}

/// A fresh empty folder for one test's files, removed by the caller's TearDown or left in /tmp.
inline std::filesystem::path temp_dir(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() /
             ("hmap_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace hmap::test

/// Skips the current test, with a message naming the folder, when a data set is absent.
#define HMAP_REQUIRE_DATA(subdir)                                                          \
  do {                                                                                     \
    if (!std::filesystem::exists(::hmap::test::data_dir() / (subdir)))                     \
      GTEST_SKIP() << "real data set " << (::hmap::test::data_dir() / (subdir)).string()   \
                   << " is absent; set HMAP_DATA_DIR to the folder of ../shared/data";     \
  } while (0)
