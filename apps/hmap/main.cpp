// hmap: maps a robot can plan on, from 3D point clouds.

#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>

#include "cli_common.hpp"
#include "hmap/core/error.hpp"

int main(int argc, char** argv) {
  CLI::App app{"hmap: hybrid height-voxel maps (HMAP) from 3D point clouds"};
  hmap::cli::configure_app(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // CLI11 quotes the argument it could not take: a newline or a terminal escape in it is
    // written as \xNN, as in every other message (hmap::Error).
    std::fprintf(stderr, "hmap: error: %s (see hmap --help)\n", hmap::one_line(e.what()).c_str());
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
