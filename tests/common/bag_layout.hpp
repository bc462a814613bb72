#pragma once
// The test bags of tests/ros/make_test_bags.py as rosbag's own index describes them: where each
// message becomes whole in the file, where the chunks lie. The truth that the linear reading of
// a bag cut off is held to (tests/ros/bag_reader_test.cpp, tests/apps/bag_cli_test.cpp).

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace hmap::test {

inline std::filesystem::path make_test_bags_script() {
  return std::filesystem::path(HMAP_TESTS_SOURCE_DIR) / "ros" / "make_test_bags.py";
}

/// Where each message of an indexed bag becomes whole, and its chunks, from rosbag's own index
/// (make_test_bags.py --layout): the truth the linear reading of a cut copy is held to.
struct BagLayout {
  std::uint64_t size = 0;
  struct Chunk {
    std::uint64_t pos = 0;
    std::uint64_t end = 0;  ///< of its data
  };
  std::vector<Chunk> chunks;
  std::vector<std::pair<std::string, std::uint64_t>> messages;  ///< topic, byte where it is whole

  static BagLayout of(const std::filesystem::path& bag) {
    // Debian's python (not a virtual env's) has the rosbag module.
    const std::string cmd = "/usr/bin/python3 " + make_test_bags_script().string() + " --layout " + bag.string();
    std::string out;
    FILE* pipe = ::popen(cmd.c_str(), "r");
    if (pipe == nullptr) return {};
    char buf[4096];
    std::size_t n = 0;
    while ((n = std::fread(buf, 1, sizeof buf, pipe)) > 0) out.append(buf, n);
    ::pclose(pipe);
    BagLayout layout;
    const auto json = nlohmann::json::parse(out);
    layout.size = json["size"];
    for (const auto& c : json["chunks"]) layout.chunks.push_back({c["pos"], c["end"]});
    for (const auto& m : json["messages"]) layout.messages.emplace_back(m["topic"], m["whole_at"]);
    return layout;
  }
  /// The messages (of `topic`, or all) whole in the first `cut` bytes.
  [[nodiscard]] std::size_t whole_before(std::uint64_t cut, const std::string& topic = "") const {
    return static_cast<std::size_t>(std::count_if(messages.begin(), messages.end(), [&](const auto& m) {
      return m.second <= cut && (topic.empty() || m.first == topic);
    }));
  }
  [[nodiscard]] std::uint64_t last_whole_at(std::uint64_t cut) const {
    std::uint64_t last = 0;
    for (const auto& m : messages) {
      if (m.second <= cut) last = std::max(last, m.second);
    }
    return last;
  }
};

inline std::string read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

inline void write_bytes(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace hmap::test
