#include "hmap/io/geotiff.hpp"

#include <gdal.h>
#include <cpl_conv.h>
#include <cpl_vsi.h>

#include <atomic>
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/io/atomic_file.hpp"

namespace hmap {

void write_ground_geotiff(const std::filesystem::path& path, const TraversabilityLayers& layers) {
  if (layers.width <= 0 || layers.height <= 0) throw Error(path.string() + ": no ground cell, nothing to export");
  GDALAllRegister();
  GDALDriverH driver = GDALGetDriverByName("GTiff");
  if (driver == nullptr) throw Error(path.string() + ": GDAL has no GTiff driver");
  static std::atomic<unsigned> counter{0};
  const std::string mem = "/vsimem/hmap_ground_" + std::to_string(counter++) + ".tif";
  const char* options[] = {"COMPRESS=DEFLATE", "TILED=YES", nullptr};
  GDALDatasetH ds = GDALCreate(driver, mem.c_str(), layers.width, layers.height, 1, GDT_Float32,
                               const_cast<char**>(options));
  if (ds == nullptr) throw Error(path.string() + ": GDAL could not create the GeoTIFF: " + CPLGetLastErrorMsg());
  const double cell = layers.cell_size;
  double transform[6] = {layers.i_min * cell, cell, 0.0, (layers.j_min + layers.height) * cell, 0.0, -cell};
  bool ok = GDALSetGeoTransform(ds, transform) == CE_None;
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  ok = ok && GDALSetRasterNoDataValue(band, std::nan("")) == CE_None;
  GDALSetDescription(band, "ground height [m]");
  std::vector<float> row(static_cast<std::size_t>(layers.width));
  for (std::int32_t r = 0; ok && r < layers.height; ++r) {
    const std::int32_t j_row = layers.height - 1 - r;  // raster row 0: the northernmost
    for (std::int32_t c = 0; c < layers.width; ++c) row[static_cast<std::size_t>(c)] = layers.ground_z[layers.index(c, j_row)];
    ok = GDALRasterIO(band, GF_Write, 0, r, layers.width, 1, row.data(), layers.width, 1, GDT_Float32, 0, 0) == CE_None;
  }
  const std::string error = ok ? "" : CPLGetLastErrorMsg();
  GDALClose(ds);
  vsi_l_offset size = 0;
  GByte* bytes = VSIGetMemFileBuffer(mem.c_str(), &size, /*bUnlinkAndSeize=*/TRUE);
  if (!ok || bytes == nullptr) {
    if (bytes != nullptr) CPLFree(bytes);
    throw Error(path.string() + ": GDAL could not write the GeoTIFF: " + error);
  }
  try {
    write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(bytes), static_cast<std::size_t>(size)));
  } catch (...) {
    CPLFree(bytes);
    throw;
  }
  CPLFree(bytes);
}

}  // namespace hmap
