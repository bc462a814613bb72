#pragma once
// The one opener of a run's scans, for the CLI and the Python package alike: KITTI folders, scan
// files, RGB-D folders (hmap::io) and recordings (hmap::ros, when it is built). It lives apart from
// both so that hmap::io need not depend on hmap::ros.

#include "hmap/io/scan_source.hpp"

namespace hmap {

/// Opens the one input of `spec` and turns its poses by its up / rotation (apply_up). Throws
/// hmap::Error for no or several inputs and, when hmap::ros is not built, for a bag; InputError
/// for what the readers refuse.
[[nodiscard]] ScanSource open_scan_source(const ScanSourceSpec& spec);

}  // namespace hmap
