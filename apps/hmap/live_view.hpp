#pragma once
// `--view` of hmap map: the browser viewer served while the map is built, updated as scans are
// integrated (hmap::serve's server-sent events), then served until Ctrl-C.

#include <CLI/CLI.hpp>

#include <chrono>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "hmap/ground/ground_patches.hpp"
#include "hmap/maps/hmap.hpp"
#include "hmap/occupancy/occupancy_grid.hpp"

namespace hmap::cli {

struct LiveViewOptions {
  bool enabled = false;
  int port = 8080;
  std::string bind = "127.0.0.1";
  /// Adds --view, --view-port and --view-bind to `cmd`.
  void add_to(CLI::App& cmd);
};

/// The server of a live view; does nothing when the options say no view.
class LiveView {
 public:
  /// Binds and starts serving an empty map (throws hmap::Error when the port is in use), and
  /// prints the URL.
  explicit LiveView(const LiveViewOptions& options);
  ~LiveView();
  LiveView(const LiveView&) = delete;
  LiveView& operator=(const LiveView&) = delete;

  /// Serves a copy of the map as it is now, at most once a second unless `final`.
  void update(const HMap& map, std::span<const GroundPatch> ground, const OccupancyGrid* grid,
              std::vector<Eigen::Vector3d> trajectory, const std::string& progress, bool final = false);
  /// After the final update: serves until Ctrl-C (SIGINT) or SIGTERM.
  void serve_until_stopped();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Serves `server`-like objects until SIGINT or SIGTERM: installs handlers that call stop().
void stop_on_signals(std::function<void()> stop);

}  // namespace hmap::cli
