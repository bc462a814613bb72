#include "hmap/sources/open_scan_source.hpp"

#ifdef HMAP_HAVE_ROS
#include "hmap/ros/bag_source.hpp"
#endif

namespace hmap {

ScanSource open_scan_source(const ScanSourceSpec& spec) {
#ifdef HMAP_HAVE_ROS
  if (!spec.bag.empty()) {
    check_one_input(spec);
    ScanSource src = ros::open_bag_source(spec);
    apply_up(src, spec);
    return src;
  }
#endif
  return open_scan_source_without_recordings(spec);  // refuses a bag by name without hmap::ros
}

}  // namespace hmap
