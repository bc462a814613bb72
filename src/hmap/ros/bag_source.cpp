#include "hmap/ros/bag_source.hpp"

#include <memory>

#include "hmap/core/error.hpp"
#include "hmap/core/format.hpp"
#include "hmap/ros/bag_reader.hpp"

namespace hmap::ros {

namespace {

class BagFrames final : public FrameReader {
 public:
  explicit BagFrames(std::unique_ptr<BagCloudReader> reader) : reader_(std::move(reader)) {}
  [[nodiscard]] PointCloud read(std::size_t index, CloudReadStats& stats, std::vector<float>* times_s) const override {
    return reader_->read(index, &stats, times_s);
  }

 private:
  std::unique_ptr<BagCloudReader> reader_;
};

}  // namespace

ScanSource open_bag_source(const ScanSourceSpec& spec) {
  BagCloudOptions options;
  options.cloud_topic = spec.cloud_topic;
  options.pose_topic = spec.pose_topic;
  if (!spec.pose_topic.empty() && !spec.tf_frames.empty()) {
    throw Error("give either --pose-topic or --tf-frames, not both");
  }
  if (!spec.tf_frames.empty()) options.map_frame = spec.tf_frames[0];
  if (spec.tf_frames.size() > 1) options.sensor_frame = spec.tf_frames[1];
  options.max_clouds = spec.max_scans;
  auto reader = std::make_unique<BagCloudReader>(spec.bag, options);
  if (spec.warn) {
    for (const auto& w : reader->warnings()) spec.warn(w);
  }
  ScanSource src;
  src.budget = spec.budget;
  src.T_map_scan.emplace();
  const std::string& topic = reader->cloud_topic();
  for (const auto& f : reader->frames()) {
    src.scans.emplace_back(topic + format("@%.6f", f.stamp));
    src.T_map_scan->push_back(f.T_map_cloud);
    src.stamps.push_back(f.stamp);
  }
  src.poses_name = spec.bag + " " + reader->pose_source();
  src.description = std::to_string(reader->frames().size()) + " clouds of " + topic +
                    (reader->cloud_topic_chosen() ? " (its only PointCloud2 topic)" : "") + " in " + spec.bag +
                    ", poses from " + reader->pose_source();
  src.frames = std::make_shared<BagFrames>(std::move(reader));
  return src;
}

}  // namespace hmap::ros
