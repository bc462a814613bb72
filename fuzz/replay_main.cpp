// fuzz_replay TARGET PATH...: feeds every file of PATH (files or folders, recursively, in name
// order) once to fuzz target TARGET, as libFuzzer does when given files. Built in ordinary
// (non-fuzzing) builds so that the hand-made corpus and every crash input ever found in
// fuzz/regressions/ are replayed by CTest, under the sanitizers of `make test-sanitize` too.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <string_view>
#include <vector>

#define HMAP_FUZZ_DECLARE(name) int hmap_fuzz_##name(const std::uint8_t* data, std::size_t size);
HMAP_FUZZ_DECLARE(pcd)
HMAP_FUZZ_DECLARE(ply)
HMAP_FUZZ_DECLARE(xyz)
HMAP_FUZZ_DECLARE(kitti_bin)
HMAP_FUZZ_DECLARE(poses)
HMAP_FUZZ_DECLARE(vtk)
HMAP_FUZZ_DECLARE(depth_png)
HMAP_FUZZ_DECLARE(intrinsics)
HMAP_FUZZ_DECLARE(hmap_file)
HMAP_FUZZ_DECLARE(pvox_binary)
HMAP_FUZZ_DECLARE(pvox_csv)
HMAP_FUZZ_DECLARE(config)
HMAP_FUZZ_DECLARE(params_cli)
HMAP_FUZZ_DECLARE(cli_flags)
#ifdef HMAP_FUZZ_HAVE_ROS
HMAP_FUZZ_DECLARE(rosbag)
HMAP_FUZZ_DECLARE(mcap)
HMAP_FUZZ_DECLARE(cdr)
#endif

namespace {

namespace fs = std::filesystem;
using Entry = int (*)(const std::uint8_t*, std::size_t);

struct Target {
  std::string_view name;
  Entry entry;
};

constexpr Target kTargets[] = {
    {"pcd", hmap_fuzz_pcd},
    {"ply", hmap_fuzz_ply},
    {"xyz", hmap_fuzz_xyz},
    {"kitti_bin", hmap_fuzz_kitti_bin},
    {"poses", hmap_fuzz_poses},
    {"vtk", hmap_fuzz_vtk},
    {"depth_png", hmap_fuzz_depth_png},
    {"intrinsics", hmap_fuzz_intrinsics},
    {"hmap_file", hmap_fuzz_hmap_file},
    {"pvox_binary", hmap_fuzz_pvox_binary},
    {"pvox_csv", hmap_fuzz_pvox_csv},
    {"config", hmap_fuzz_config},
    {"params_cli", hmap_fuzz_params_cli},
    {"cli_flags", hmap_fuzz_cli_flags},
#ifdef HMAP_FUZZ_HAVE_ROS
    {"rosbag", hmap_fuzz_rosbag},
    {"mcap", hmap_fuzz_mcap},
    {"cdr", hmap_fuzz_cdr},
#endif
};

void collect(const fs::path& path, std::vector<fs::path>& files) {
  if (fs::is_directory(path)) {
    for (const auto& entry : fs::recursive_directory_iterator(path)) {
      if (entry.is_regular_file()) files.push_back(entry.path());
    }
  } else {
    files.push_back(path);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: fuzz_replay TARGET PATH...\n");
    return 2;
  }
  const std::string_view name = argv[1];
  const auto* target = std::find_if(std::begin(kTargets), std::end(kTargets),
                                    [&](const Target& t) { return t.name == name; });
  if (target == std::end(kTargets)) {
    std::fprintf(stderr, "fuzz_replay: unknown target %s\n", argv[1]);
    return 2;
  }
  std::vector<fs::path> files;
  for (int i = 2; i < argc; ++i) {
    if (fs::exists(argv[i])) collect(argv[i], files);
  }
  std::sort(files.begin(), files.end());
  for (const auto& file : files) {
    std::ifstream in(file, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::printf("%s\n", file.c_str());
    std::fflush(stdout);
    target->entry(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  }
  std::printf("fuzz_replay %s: %zu inputs, no crash\n", argv[1], files.size());
  return 0;
}
