// hmap bag-info, and ROS 1 bags as a scan source (hmap map --bag). Built with hmap::ros only.

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
  std::printf("path:        %s\nversion:     %u.%u\nduration:    %.3f s (%.6f to %.6f)\nmessages:    %zu\n"
              "chunks:      %zu\ncompression: %s\ntopics:\n",
              path.c_str(), info.version / 100, info.version % 100, info.end_time - info.start_time, info.start_time,
              info.end_time, info.messages, info.chunks, info.compression.c_str());
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
  ScanSource src;
  src.T_map_scan.emplace();
  for (const auto& f : reader->frames()) {
    src.scans.emplace_back(sensors.cloud_topic + format("@%.6f", f.stamp));
    src.T_map_scan->push_back(f.T_map_cloud);
    src.stamps.push_back(f.stamp);
  }
  src.poses_name = sensors.bag + " " + reader->pose_source();
  src.description = std::to_string(reader->frames().size()) + " clouds of " + sensors.cloud_topic + " in " + sensors.bag +
                    ", poses from " + reader->pose_source();
  src.frames = std::make_shared<BagFrames>(std::move(reader));
  return src;
}

void add_bag_info_command(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto* cmd = app.add_subcommand("bag-info", "List the topics of a ROS 1 bag (types, message counts, compression)");
  cmd->add_option("bag", *path, "ROS 1 bag file")->required();
  cmd->callback([path] { run_bag_info(*path); });
}

}  // namespace hmap::cli

#endif  // HMAP_HAVE_ROS
