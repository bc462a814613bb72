#include "hmap/io/geotiff.hpp"

#include <dlfcn.h>
#include <gdal.h>
#include <cpl_conv.h>
#include <cpl_vsi.h>

#include <atomic>
#include <cmath>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "hmap/core/error.hpp"
#include "hmap/io/atomic_file.hpp"

namespace hmap {

namespace {

// GDAL is loaded when a GeoTIFF is written, not when hmap starts: linked, its hundred libraries
// cost every hmap command 60-70 ms of dynamic loading (measured: a program linking libgdal alone
// starts in 60-70 ms, one linking nothing in under 5), which a run of `hmap info` or the CLI tests
// paid for a format few runs write. The prototypes come from GDAL's headers.
struct Gdal {
  decltype(&::GDALAllRegister) AllRegister = nullptr;
  decltype(&::GDALGetDriverByName) GetDriverByName = nullptr;
  decltype(&::GDALCreate) Create = nullptr;
  decltype(&::CPLGetLastErrorMsg) GetLastErrorMsg = nullptr;
  decltype(&::GDALSetGeoTransform) SetGeoTransform = nullptr;
  decltype(&::GDALGetRasterBand) GetRasterBand = nullptr;
  decltype(&::GDALSetRasterNoDataValue) SetRasterNoDataValue = nullptr;
  decltype(&::GDALSetDescription) SetDescription = nullptr;
  decltype(&::GDALRasterIO) RasterIO = nullptr;
  decltype(&::GDALClose) Close = nullptr;
  decltype(&::VSIGetMemFileBuffer) GetMemFileBuffer = nullptr;
  decltype(&::VSIFree) Free = nullptr;
};

template <class F>
void bind(void* lib, F& f, const char* name, std::string& missing) {
  f = reinterpret_cast<F>(dlsym(lib, name));
  if (f == nullptr) missing += std::string(missing.empty() ? "" : ", ") + name;
}

/// GDAL's functions, loaded once; throws Error naming the library when it cannot be loaded.
const Gdal& gdal() {
  static Gdal api;
  static std::string error;
  static std::once_flag once;
  std::call_once(once, [] {
    void* lib = dlopen(HMAP_GDAL_SONAME, RTLD_NOW | RTLD_LOCAL);
    if (lib == nullptr) {
      const char* why = dlerror();
      error = std::string("GeoTIFF needs GDAL (" HMAP_GDAL_SONAME ", Debian's libgdal32): ") + (why ? why : "not found");
      return;
    }
    std::string missing;
    bind(lib, api.AllRegister, "GDALAllRegister", missing);
    bind(lib, api.GetDriverByName, "GDALGetDriverByName", missing);
    bind(lib, api.Create, "GDALCreate", missing);
    bind(lib, api.GetLastErrorMsg, "CPLGetLastErrorMsg", missing);
    bind(lib, api.SetGeoTransform, "GDALSetGeoTransform", missing);
    bind(lib, api.GetRasterBand, "GDALGetRasterBand", missing);
    bind(lib, api.SetRasterNoDataValue, "GDALSetRasterNoDataValue", missing);
    bind(lib, api.SetDescription, "GDALSetDescription", missing);
    bind(lib, api.RasterIO, "GDALRasterIO", missing);
    bind(lib, api.Close, "GDALClose", missing);
    bind(lib, api.GetMemFileBuffer, "VSIGetMemFileBuffer", missing);
    bind(lib, api.Free, "VSIFree", missing);
    if (!missing.empty()) error = std::string(HMAP_GDAL_SONAME " lacks ") + missing;
  });
  if (!error.empty()) throw Error(error);
  return api;
}

}  // namespace

void write_ground_geotiff(const std::filesystem::path& path, const TraversabilityLayers& layers) {
  if (layers.width <= 0 || layers.height <= 0) throw Error(path.string() + ": no ground cell, nothing to export");
  const Gdal& g = gdal();
  g.AllRegister();
  GDALDriverH driver = g.GetDriverByName("GTiff");
  if (driver == nullptr) throw Error(path.string() + ": GDAL has no GTiff driver");
  static std::atomic<unsigned> counter{0};
  const std::string mem = "/vsimem/hmap_ground_" + std::to_string(counter++) + ".tif";
  const char* options[] = {"COMPRESS=DEFLATE", "TILED=YES", nullptr};
  GDALDatasetH ds = g.Create(driver, mem.c_str(), layers.width, layers.height, 1, GDT_Float32,
                               const_cast<char**>(options));
  if (ds == nullptr) throw Error(path.string() + ": GDAL could not create the GeoTIFF: " + g.GetLastErrorMsg());
  const double cell = layers.cell_size;
  double transform[6] = {layers.i_min * cell, cell, 0.0, (layers.j_min + layers.height) * cell, 0.0, -cell};
  bool ok = g.SetGeoTransform(ds, transform) == CE_None;
  GDALRasterBandH band = g.GetRasterBand(ds, 1);
  ok = ok && g.SetRasterNoDataValue(band, std::nan("")) == CE_None;
  g.SetDescription(band, "ground height [m]");
  std::vector<float> row(static_cast<std::size_t>(layers.width));
  for (std::int32_t r = 0; ok && r < layers.height; ++r) {
    const std::int32_t j_row = layers.height - 1 - r;  // raster row 0: the northernmost
    for (std::int32_t c = 0; c < layers.width; ++c) row[static_cast<std::size_t>(c)] = layers.ground_z[layers.index(c, j_row)];
    ok = g.RasterIO(band, GF_Write, 0, r, layers.width, 1, row.data(), layers.width, 1, GDT_Float32, 0, 0) == CE_None;
  }
  const std::string error = ok ? "" : g.GetLastErrorMsg();
  g.Close(ds);
  vsi_l_offset size = 0;
  GByte* bytes = g.GetMemFileBuffer(mem.c_str(), &size, /*bUnlinkAndSeize=*/TRUE);
  if (!ok || bytes == nullptr) {
    if (bytes != nullptr) g.Free(bytes);
    throw Error(path.string() + ": GDAL could not write the GeoTIFF: " + error);
  }
  try {
    write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(bytes), static_cast<std::size_t>(size)));
  } catch (...) {
    g.Free(bytes);
    throw;
  }
  g.Free(bytes);
}

}  // namespace hmap
