// The command line of `hmap`: the global options and every command.

#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>
#include <string>

#include "cli_common.hpp"
#include "hmap/io/config.hpp"

namespace hmap::cli {

void configure_app(CLI::App& app) {
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("hmap 0.1.0"));
  // Read while parsing, before any subcommand runs.
  app.add_option_function<std::size_t>(
         "--max-memory", [](std::size_t mib) { memory_budget().bytes = mib << 20; },
         "Memory budget [MiB]: what an input asks beyond it (exported points, OctoMap leaves, PVOX voxels) is refused "
         "before it is allocated, and the maps of map, slam and compare are checked after every scan (default 2048)")
      ->check(CLI::Range(std::size_t{4}, std::size_t{1} << 24));
  add_map_command(app);
  add_merge_command(app);
  add_info_command(app);
  add_export_command(app);
  add_bench_command(app);
  add_render_command(app);
  add_eval_command(app);
  add_simulate_command(app);
  add_demo_command(app);
  add_compare_command(app);
#ifdef HMAP_HAVE_PVOX
  add_pvox_command(app);
  add_experiment_command(app);
#endif
#ifdef HMAP_HAVE_SLAM
  add_slam_command(app);
#endif
#ifdef HMAP_HAVE_ROS
  add_bag_info_command(app);
#endif
#ifdef HMAP_HAVE_VIEW
  add_view_command(app);
#endif
  auto* params_cmd = app.add_subcommand("params", "Print every parameter of a preset with its unit and its valid range");
  auto preset = std::make_shared<std::string>("outdoor");
  params_cmd->add_option("--preset", *preset, "indoor, room or outdoor")->capture_default_str();
  params_cmd->callback([preset] { std::fputs(params_to_yaml(hmap::preset(*preset)).c_str(), stdout); });
}

}  // namespace hmap::cli
