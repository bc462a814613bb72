// hmap: maps a robot can plan on, from 3D point clouds.

#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>

#include "cli_common.hpp"
#include "hmap/core/error.hpp"
#include "hmap/io/config.hpp"

int main(int argc, char** argv) {
  CLI::App app{"hmap: hybrid height-voxel maps (HMAP) from 3D point clouds"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("hmap 0.1.0"));
  // Read while parsing, before any subcommand runs.
  app.add_option_function<std::size_t>(
         "--max-memory", [](std::size_t mib) { hmap::cli::memory_budget().bytes = mib << 20; },
         "Memory budget [MiB]: what an input asks beyond it (exported points, OctoMap leaves, PVOX voxels) is refused "
         "before it is allocated (default 2048)")
      ->check(CLI::Range(std::size_t{16}, std::size_t{1} << 24));
  hmap::cli::add_map_command(app);
  hmap::cli::add_info_command(app);
  hmap::cli::add_export_command(app);
  hmap::cli::add_bench_command(app);
  hmap::cli::add_render_command(app);
  hmap::cli::add_eval_command(app);
  hmap::cli::add_simulate_command(app);
  hmap::cli::add_demo_command(app);
  hmap::cli::add_compare_command(app);
#ifdef HMAP_HAVE_PVOX
  hmap::cli::add_pvox_command(app);
  hmap::cli::add_experiment_command(app);
#endif
#ifdef HMAP_HAVE_SLAM
  hmap::cli::add_slam_command(app);
#endif
#ifdef HMAP_HAVE_ROS
  hmap::cli::add_bag_info_command(app);
#endif
  auto* params_cmd = app.add_subcommand("params", "Print every parameter of a preset with its unit and its valid range");
  auto preset = std::make_shared<std::string>("outdoor");
  params_cmd->add_option("--preset", *preset, "indoor or outdoor")->capture_default_str();
  params_cmd->callback([preset] { std::fputs(hmap::params_to_yaml(hmap::preset(*preset)).c_str(), stdout); });
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "hmap: error: %s (see hmap --help)\n", e.what());
    return 2;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "hmap: error: out of memory (the memory budget is hmap --max-memory MIB)\n");
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hmap: error: %s\n", e.what());
    return 2;
  }
  return 0;
}
