#pragma once
// Reader for VTK legacy files (.vtk): the POINTS of a POLYDATA or UNSTRUCTURED_GRID data set, ASCII
// or BINARY (big-endian, as the format fixes). Cells, point data and other sections are ignored.

#include <filesystem>

#include "hmap/core/types.hpp"
#include "hmap/io/cloud_stats.hpp"

namespace hmap {

/// Reads the points of a VTK legacy file. Header: "# vtk DataFile Version x.y", a title line,
/// "ASCII" or "BINARY", "DATASET POLYDATA" (or UNSTRUCTURED_GRID), then "POINTS n type" with type
/// float, double, int, ... followed by 3n numbers over any number of lines. Non-finite points are
/// dropped and counted. Throws InputError naming the line (ASCII) or byte (BINARY) of a malformed
/// header, a non-number, or data that ends before 3n values; n is checked against the file size
/// before anything is allocated.
[[nodiscard]] PointCloud read_vtk(const std::filesystem::path& path, CloudReadStats* stats = nullptr);

}  // namespace hmap
