// Built instead of rosbag_access.cpp when Debian's ROS 1 libraries are absent (CMakeLists.txt):
// MCAP files and rosbag2 folders still read, a ROS 1 bag is refused with the packages to install.
#include <stdexcept>

#include "hmap/ros/recording_access.hpp"

namespace hmap::ros::access {

std::unique_ptr<Recording> open_ros1_bag(const std::string& /*path*/) {
  throw std::runtime_error(
      "a ROS 1 bag, and this hmap was built without ROS 1 bag support: apt-get install librosbag-dev "
      "libsensor-msgs-dev libnav-msgs-dev libtf2-msgs-dev, then configure and build again");
}

std::unique_ptr<Recording> open_scanned_ros1_bag(const std::string& path, std::string /*bytes*/) {
  return open_ros1_bag(path);
}

}  // namespace hmap::ros::access
