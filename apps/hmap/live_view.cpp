#include "live_view.hpp"

#include <csignal>
#include <cstdio>
#include <thread>

#include "hmap/serve/view_server.hpp"

namespace hmap::cli {

std::filesystem::path view_web_root();  // cmd_view.cpp

namespace {

std::function<void()> g_stop;

void on_signal(int) {
  // cpp-httplib's stop() shuts the listening socket down and closes it: system calls only.
  if (g_stop) g_stop();
}

}  // namespace

void stop_on_signals(std::function<void()> stop) {
  g_stop = std::move(stop);
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}

void LiveViewOptions::add_to(CLI::App& cmd) {
  cmd.add_flag("--view", enabled, "Serve the browser viewer (hmap view) while mapping, updated as scans come in; "
                                  "then serve the final map until Ctrl-C");
  cmd.add_option("--view-port", port, "Port of --view (0: any free port)")->check(CLI::Range(0, 65535))->capture_default_str();
  cmd.add_option("--view-bind", bind, "Address of --view")->capture_default_str();
}

struct LiveView::Impl {
  std::unique_ptr<serve::ViewServer> server;
  std::thread thread;
  std::chrono::steady_clock::time_point last{};
};

LiveView::LiveView(const LiveViewOptions& o) : impl_(std::make_unique<Impl>()) {
  if (!o.enabled) return;
  Params p;
  auto empty = std::make_shared<const view::MapScene>(HMap(p), std::vector<GroundPatch>{}, std::nullopt,
                                                      std::vector<Eigen::Vector3d>{});
  impl_->server = std::make_unique<serve::ViewServer>(empty, serve::ServerOptions{o.bind, o.port, view_web_root(), HMAP_THREE_DIR});
  impl_->server->bind();
  std::printf("open %s in a browser to watch the map grow\n", impl_->server->url().c_str());
  std::fflush(stdout);
  impl_->thread = std::thread([s = impl_->server.get()] { s->run(); });
}

LiveView::~LiveView() {
  if (!impl_->server) return;
  impl_->server->stop();
  if (impl_->thread.joinable()) impl_->thread.join();  // serve_until_stopped() may have joined it
}

void LiveView::update(const HMap& map, std::span<const GroundPatch> ground, const OccupancyGrid* grid,
                      std::vector<Eigen::Vector3d> trajectory, const std::string& progress, bool final) {
  if (!impl_->server) return;
  const auto now = std::chrono::steady_clock::now();
  if (!final && now - impl_->last < std::chrono::seconds(1)) return;
  impl_->last = now;
  impl_->server->set_scene(std::make_shared<const view::MapScene>(view::snapshot(map, ground, grid, std::move(trajectory))),
                           progress);
}

void LiveView::serve_until_stopped() {
  if (!impl_->server) return;
  std::printf("still serving %s (Ctrl-C stops)\n", impl_->server->url().c_str());
  std::fflush(stdout);
  stop_on_signals([s = impl_->server.get()] { s->stop(); });
  impl_->thread.join();
  stop_on_signals(nullptr);
}

}  // namespace hmap::cli
