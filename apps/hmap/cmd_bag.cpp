// hmap bag-info, and recordings as a scan source (hmap map --bag): ROS 1 bags, MCAP files and
// rosbag2 folders alike (hmap::ros tells them apart). Built with hmap::ros only.

#ifdef HMAP_HAVE_ROS

#include <cstdio>

#include "cli_common.hpp"
#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/ros/bag_reader.hpp"

namespace hmap::cli {

namespace {

class BagFrames final : public FrameReader {
 public:
  explicit BagFrames(std::unique_ptr<ros::BagCloudReader> reader) : reader_(std::move(reader)) {}
  [[nodiscard]] PointCloud read(std::size_t index, CloudReadStats& stats, std::vector<float>* times_s) const override {
    return reader_->read(index, &stats, times_s);
  }

 private:
  std::unique_ptr<ros::BagCloudReader> reader_;
};

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

ScanSource open_bag_source(const ScanSourceOptions& sensors, std::size_t max_scans) {
  ros::BagCloudOptions options;
  options.cloud_topic = sensors.cloud_topic;
  options.pose_topic = sensors.pose_topic;
  if (!sensors.pose_topic.empty() && !sensors.tf_frames.empty()) {
    throw Error("give either --pose-topic or --tf-frames, not both");
  }
  if (!sensors.tf_frames.empty()) options.map_frame = sensors.tf_frames[0];
  if (sensors.tf_frames.size() > 1) options.sensor_frame = sensors.tf_frames[1];
  options.max_clouds = max_scans;
  auto reader = std::make_unique<ros::BagCloudReader>(sensors.bag, options);
  for (const auto& w : reader->warnings()) std::fprintf(stderr, "hmap: warning: %s\n", w.c_str());
  ScanSource src;
  src.T_map_scan.emplace();
  const std::string& topic = reader->cloud_topic();
  for (const auto& f : reader->frames()) {
    src.scans.emplace_back(topic + format("@%.6f", f.stamp));
    src.T_map_scan->push_back(f.T_map_cloud);
    src.stamps.push_back(f.stamp);
  }
  src.poses_name = sensors.bag + " " + reader->pose_source();
  src.description = std::to_string(reader->frames().size()) + " clouds of " + topic +
                    (reader->cloud_topic_chosen() ? " (its only PointCloud2 topic)" : "") + " in " + sensors.bag +
                    ", poses from " + reader->pose_source();
  src.frames = std::make_shared<BagFrames>(std::move(reader));
  return src;
}

void add_bag_info_command(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto* cmd = app.add_subcommand("bag-info", "List the topics of a recording (types, message counts, time range, compression)");
  cmd->add_option("bag", *path, "ROS 1 bag, MCAP file or rosbag2 folder")->required();
  cmd->callback([path] { run_bag_info(*path); });
}

}  // namespace hmap::cli

#endif  // HMAP_HAVE_ROS
