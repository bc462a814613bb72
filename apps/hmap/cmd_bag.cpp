// hmap bag-info: ROS 1 bags, MCAP files and rosbag2 folders alike (hmap::ros tells them apart).
// Built with hmap::ros only; recordings as a scan source (hmap map --bag) are the library's
// (hmap/ros/bag_source.hpp, reached through open_scan_source).

#ifdef HMAP_HAVE_ROS

#include <cstdio>

#include "cli_common.hpp"
#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/ros/bag_reader.hpp"

namespace hmap::cli {

namespace {

void run_bag_info(const std::string& path) {
  const ros::BagInfo info = ros::read_bag_info(path);
  for (const auto& w : info.warnings) std::fprintf(stderr, "hmap: warning: %s\n", w.c_str());
  std::printf("path:        %s\nformat:      %s\n", path.c_str(), info.format.c_str());
  if (info.version != 0) std::printf("version:     %u.%u\n", info.version / 100, info.version % 100);
  std::printf("duration:    %.3f s (%.6f to %.6f)\nmessages:    %zu\n"
              "chunks:      %zu\ncompression: %s\n",
              info.end_time - info.start_time, info.start_time,
              info.end_time, info.messages, info.chunks, info.compression.c_str());
  if (info.scanned_to != 0) {
    std::printf("index:       none usable: read linearly, %s at byte %llu of %llu\n",
                info.scanned_to < info.file_size ? "cut off" : "to its end",
                static_cast<unsigned long long>(info.scanned_to), static_cast<unsigned long long>(info.file_size));
  }
  std::printf("topics:\n");
  for (const auto& t : info.topics) std::printf("  %-32s %6zu msgs  %s\n", t.name.c_str(), t.messages, t.type.c_str());
}

}  // namespace

void add_bag_info_command(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto* cmd = app.add_subcommand("bag-info", "List the topics of a recording (types, message counts, time range, compression)");
  cmd->add_option("bag", *path, "ROS 1 bag, MCAP file or rosbag2 folder")->required();
  cmd->callback([path] { run_bag_info(*path); });
}

}  // namespace hmap::cli

#endif  // HMAP_HAVE_ROS
