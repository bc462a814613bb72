// fuzz_seeds DATA_DIR OUT_DIR: writes the seeds of the fuzz targets whose files the library itself
// makes (.hmap maps, PVOX maps, parameter files), in the input form each target takes (see the
// mode byte of hmap_file_fuzz.cpp and pvox_binary_fuzz.cpp). The maps are built from a slice of
// DATA_DIR/balm_os0 (scans 0 and 1, every 40th point), or from a small synthetic room without it.
#include <zstd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "hmap/core/params.hpp"
#include "hmap/io/config.hpp"
#include "hmap/io/hmap_file.hpp"
#include "hmap/io/kitti.hpp"
#include "hmap/io/poses.hpp"
#include "hmap/io/read_support.hpp"
#include "hmap/maps/mapper.hpp"
#include "hmap/pvox/serialize.hpp"

namespace fs = std::filesystem;

namespace {

void write(const fs::path& path, std::string_view bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::uint64_t get_u64(std::string_view bytes, std::size_t at) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(bytes[at + static_cast<std::size_t>(i)]);
  return v;
}

/// Scans with their poses: a slice of balm_os0, or a synthetic box room seen from two places.
std::vector<std::pair<hmap::PointCloud, hmap::Pose>> scans(const fs::path& data) {
  std::vector<std::pair<hmap::PointCloud, hmap::Pose>> out;
  const fs::path seq = data / "balm_os0";
  if (fs::exists(seq / "poses.txt")) {
    const hmap::PoseList poses = hmap::read_poses(seq / "poses.txt");
    for (int k = 0; k < 2; ++k) {
      char name[32];
      std::snprintf(name, sizeof name, "%06d.bin", k);
      const hmap::PointCloud full = hmap::read_kitti_bin(seq / "velodyne" / name);
      hmap::PointCloud slice;
      for (std::size_t i = 0; i < full.size(); i += 40) slice.push_back(full[i]);
      out.emplace_back(slice, poses[static_cast<std::size_t>(k)]);
    }
    return out;
  }
  hmap::PointCloud room;
  for (int a = -20; a <= 20; ++a) {
    for (int b = -20; b <= 20; ++b) {
      room.emplace_back(0.25f * static_cast<float>(a), 0.25f * static_cast<float>(b), -1.5f);  // floor
      room.emplace_back(5.0f, 0.25f * static_cast<float>(a), 0.1f * static_cast<float>(b + 20) - 1.5f);  // wall
    }
  }
  out.emplace_back(room, hmap::Pose::Identity());
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: fuzz_seeds DATA_DIR OUT_DIR\n");
    return 2;
  }
  const fs::path data = argv[1];
  const fs::path out = argv[2];
  const auto input = scans(data);

  // .hmap: the empty map and a small real one, each as modes 0 and 1, and their payloads as mode 2.
  hmap::Params params = hmap::outdoor_preset();
  params.map.cell_size = 0.5;
  hmap::Mapper mapper(params);
  const hmap::HMap empty(params);
  for (const auto& [points, pose] : input) mapper.integrate(points, pose);
  // The real one with a few cell centroids (the version-3 section), as the SLAM saves them.
  hmap::CellCentroids centroids(params.map.cell_size);
  centroids.add(1.1, -2.3, 3.0);
  centroids.add(-4.05, 0.2, 1.0);
  centroids.add(-4.2, 0.1, 2.5);
  int n = 0;
  for (const hmap::HMap* map : {&empty, static_cast<const hmap::HMap*>(&mapper.map())}) {
    const fs::path file = out / "tmp.hmap";
    hmap::save_hmap(file, *map, {}, nullptr, map == &empty ? nullptr : &centroids);
    const std::string bytes = hmap::detail::read_file_bytes(file);
    fs::remove(file);
    const std::size_t json = static_cast<std::size_t>(get_u64(bytes, 16));
    const std::size_t sizes_at = 24 + json;
    std::string payload(static_cast<std::size_t>(get_u64(bytes, sizes_at)), '\0');
    const std::size_t c = static_cast<std::size_t>(get_u64(bytes, sizes_at + 8));
    const std::size_t d = ZSTD_decompress(payload.data(), payload.size(), bytes.data() + sizes_at + 16, c);
    if (ZSTD_isError(d) != 0) return 1;
    const std::string id = std::to_string(n++);
    write(out / "hmap_file" / ("file" + id), std::string(1, '\0') + bytes);
    write(out / "hmap_file" / ("fixed" + id), std::string(1, '\1') + bytes);
    write(out / "hmap_file" / ("payload" + id), std::string(1, '\2') + payload);
  }

  // PVOX: the same scans in a 0.5 m voxel map; CSV: its first lines.
  hmap::pvox::VoxelMap voxels(0.5);
  for (const auto& [points, pose] : input) {
    (void)voxels.insert(points, pose, hmap::pvox::InsertParams{});
  }
  const std::vector<std::uint8_t> pvox = hmap::pvox::encode_binary(voxels);
  const std::string pvox_bytes(pvox.begin(), pvox.end());
  write(out / "pvox_binary" / "file", std::string(1, '\0') + pvox_bytes);
  write(out / "pvox_binary" / "fixed", std::string(1, '\1') + pvox_bytes);
  {
    std::string payload(static_cast<std::size_t>(get_u64(pvox_bytes, 64)), '\0');
    const std::size_t d = ZSTD_decompress(payload.data(), payload.size(), pvox_bytes.data() + 80,
                                          static_cast<std::size_t>(get_u64(pvox_bytes, 72)));
    if (ZSTD_isError(d) != 0) return 1;
    write(out / "pvox_binary" / "payload", std::string(1, '\2') + pvox_bytes.substr(16, 48) + payload);
  }
  std::string csv = hmap::pvox::voxels_csv(voxels);
  std::size_t cut = 0;
  for (int line = 0; line < 40 && cut != std::string::npos; ++line) cut = csv.find('\n', cut + 1);
  write(out / "pvox_csv" / "voxels.csv", csv.substr(0, cut == std::string::npos ? csv.size() : cut + 1));
  write(out / "pvox_csv" / "points.csv", hmap::pvox::points_csv(input.front().first).substr(0, 2000));

  // Parameter files: every parameter, flat, for each preset.
  write(out / "config" / "outdoor.yaml", hmap::params_to_yaml(hmap::outdoor_preset()));
  write(out / "config" / "indoor.yaml", hmap::params_to_yaml(hmap::indoor_preset()));
  std::printf("fuzz_seeds: wrote the hmap_file, pvox_binary, pvox_csv and config seeds to %s\n", out.c_str());
  return 0;
}
