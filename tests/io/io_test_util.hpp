#pragma once
// Helpers for the hmap::io tests: a scratch folder per test, binary encoders, error checks.

#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "common/test_data.hpp"
#include "hmap/core/error.hpp"

namespace hmap::test {

/// A fixture with a fresh folder for the test's files, removed afterwards.
class IoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = temp_dir(std::string(info->test_suite_name()) + "_" + info->name());
  }
  void TearDown() override {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }

  /// Writes `bytes` to dir_/name and returns the path.
  std::filesystem::path write(const std::string& name, std::string_view bytes) const {
    const auto path = dir_ / name;
    std::filesystem::create_directories(path.parent_path());
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
  }

  std::filesystem::path dir_;
};

/// Appends the bytes of `value` in little-endian (or big-endian) order.
template <typename T>
void put(std::string& out, T value, std::endian order = std::endian::little) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if (order != std::endian::native) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  }
  out.append(bytes, sizeof(T));
}

/// `raw` as a valid LZF stream made only of literal runs: a control byte c < 32 copies the next
/// c + 1 bytes.
inline std::string lzf_literals(std::string_view raw) {
  std::string out;
  while (!raw.empty()) {
    const std::size_t run = raw.size() < 32 ? raw.size() : 32;
    out.push_back(static_cast<char>(run - 1));
    out.append(raw.substr(0, run));
    raw.remove_prefix(run);
  }
  return out;
}

/// The what() of the InputError `f` throws, or a note that it threw something else or nothing.
template <typename F>
std::string input_error_of(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("<not an InputError: ") + e.what() + ">";
  }
  return "<no exception>";
}

inline ::testing::AssertionResult contains(const std::string& text, std::string_view part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' does not contain '" << part << "'";
}

}  // namespace hmap::test
