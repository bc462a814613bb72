#include "hmap/core/sensor_profile.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "hmap/core/format.hpp"

namespace hmap {

SensorProfile profile_scan(std::span<const Point3f> points_sensor) {
  SensorProfile out;
  constexpr std::size_t kMaxPoints = 200000;
  const std::size_t stride = std::max<std::size_t>(1, points_sensor.size() / kMaxPoints);
  constexpr double kBin = 0.05 * std::numbers::pi / 180.0;
  constexpr int kBins = static_cast<int>(std::numbers::pi / kBin) + 2;
  std::vector<std::uint32_t> hist(static_cast<std::size_t>(kBins), 0);
  std::vector<std::uint32_t> near_hist(static_cast<std::size_t>(kBins), 0);  // points 2-5 m away
  std::vector<float> ranges;
  std::array<bool, 360> azimuths{};
  std::size_t far = 0;
  std::size_t near = 0;
  for (std::size_t k = 0; k < points_sensor.size(); k += stride) {
    const Point3f& q = points_sensor[k];
    if (!q.allFinite()) continue;
    const double h = std::hypot(static_cast<double>(q.x()), static_cast<double>(q.y()));
    const double r = std::hypot(h, static_cast<double>(q.z()));
    ++out.points;
    ranges.push_back(static_cast<float>(r));
    if (h > 0.0) {
      const double az = std::atan2(static_cast<double>(q.y()), static_cast<double>(q.x())) * 180.0 / std::numbers::pi;  // (-180, 180]
      azimuths[static_cast<std::size_t>(std::clamp(static_cast<int>(std::floor(az + 180.0)), 0, 359))] = true;
    }
    if (r < 2.0) continue;
    const double elevation = std::atan2(static_cast<double>(q.z()), h);  // in [−π/2, π/2]
    const auto bin = static_cast<std::size_t>(std::clamp(
        static_cast<int>((elevation + 0.5 * std::numbers::pi) / kBin), 0, kBins - 1));
    if (r < 5.0) {
      ++near_hist[bin];
      ++near;
      continue;
    }
    ++hist[bin];
    ++far;
  }
  out.azimuth_coverage = static_cast<double>(std::count(azimuths.begin(), azimuths.end(), true)) / 360.0;
  const bool near_rings = far < 1000 && out.azimuth_coverage > 0.5;
  if (near_rings) {
    // Everything within 5 m and all around: a LiDAR in a small closed room. Its rings are read
    // from 2 m on (blurred more by the beams' offsets from the origin: a VLP-16's 2 deg rings
    // stay apart, an HDL-64's may not, and are then not found). A narrower view (a depth
    // camera's) is never read this near: its rows would pass for rings.
    hist.swap(near_hist);
    far = near;
  }
  if (!ranges.empty()) {
    const auto p95 = ranges.begin() + static_cast<std::ptrdiff_t>(0.95 * static_cast<double>(ranges.size() - 1));
    std::nth_element(ranges.begin(), p95, ranges.end());
    out.range_p95 = *p95;
  }
  if (far < 1000) return out;
  // Rings: runs of populated bins, each at its count-weighted centre.
  const double min_count = std::max(3.0, 0.001 * static_cast<double>(far));
  std::vector<double> centres;
  std::size_t populated = 0;
  double sum = 0.0;
  double weighted = 0.0;
  double in_rings = 0.0;
  for (int b = 0; b <= kBins; ++b) {
    const double c = b < kBins ? static_cast<double>(hist[static_cast<std::size_t>(b)]) : 0.0;
    if (c >= min_count) {
      sum += c;
      weighted += c * (b + 0.5);
      in_rings += c;
      ++populated;
    } else if (sum > 0.0) {
      centres.push_back(weighted / sum * kBin);
      sum = 0.0;
      weighted = 0.0;
    }
  }
  if (centres.size() < 4) return out;
  // Near by, a LiDAR's points lie on its rings (the bins that pass the count); elevations spread
  // thinly over the span (a few thousand points of a sweeping laser) pass the count in a few bins
  // by chance, holding a small share of them.
  if (near_rings && in_rings < 0.8 * static_cast<double>(far)) return out;
  const double span_bins = (centres.back() - centres.front()) / kBin + 1.0;
  if (static_cast<double>(populated) >= 0.5 * span_bins) return out;
  std::vector<double> steps;
  for (std::size_t k = 1; k < centres.size(); ++k) steps.push_back(centres[k] - centres[k - 1]);
  std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
  // Steps under four bins are the bins' own pattern (a depth camera's 0.1° rows), not rings.
  if (steps[steps.size() / 2] < 4.0 * kBin) return out;
  out.rings = static_cast<int>(centres.size());
  out.ring_spacing = steps[steps.size() / 2];
  return out;
}

std::string preset_for_sensor(const SensorProfile& sensor, std::string* reason) {
  // Fewer points than any real scan has (a depth image, a LiDAR sweep: 10^4 and more) tell
  // nothing about the sensor: a pose file given as a scan is one point at 1 m.
  constexpr std::size_t kMinPoints = 1000;
  if (sensor.points < kMinPoints) {
    if (reason != nullptr) *reason = format("the first scan has %zu points, too few to tell the sensor", sensor.points);
    return "outdoor";
  }
  // The presets from the finest up, each with a cell of 1 % of its range: the first whose range
  // holds 95 % of the points, so that a coarser one would see nothing more and lose the detail.
  const double indoor_reach = indoor_preset().map.max_range;
  const double room_reach = room_preset().map.max_range;
  const auto why = [&](const std::string& where) {
    if (reason != nullptr) *reason = format("95 %% of the first scan's points within %.1f m, ", sensor.range_p95) + where;
  };
  if (sensor.range_p95 <= indoor_reach) {
    // The indoor preset's 0.05 m cells are the paper's for a depth camera: a LiDAR's rings leave
    // them sparse and its noise (2-3 cm) fills them. A LiDAR that starts in a small room takes the
    // room preset (and adapt_to_sensor gives it its reach beyond the room).
    if (is_spinning_lidar(sensor)) {
      why(format("inside the indoor preset's %.0f m range, but a LiDAR (%d rings): the room preset", indoor_reach,
                 sensor.rings));
      return "room";
    }
    why(format("inside the indoor preset's %.0f m range", indoor_reach));
    return "indoor";
  }
  if (sensor.range_p95 <= room_reach) {
    why(format("beyond the indoor preset's %.0f m range, inside the room preset's %.0f m", indoor_reach, room_reach));
    return "room";
  }
  why(format("beyond the indoor preset's %.0f m range and the room preset's %.0f m", indoor_reach, room_reach));
  return "outdoor";
}

std::vector<ChosenDefault> adapt_to_sensor(Params& p, const Params& preset_params, const SensorProfile& sensor,
                                           bool max_range_named, bool gap_named) {
  std::vector<ChosenDefault> chosen;
  // Neighbouring rings hit a wall at a horizontal distance d about d · tan(spacing) apart in
  // height (more by 1/cos² of the elevation: 7 % at a VLP-16's 15 deg; the rings that reach a
  // far wall are the near-horizontal ones), and by a margin for uneven rings.
  constexpr double kMargin = 1.1;
  const double slope =
      sensor.rings > 0 ? std::round(kMargin * std::tan(sensor.ring_spacing) * 1e4) / 1e4 : 0.0;
  const std::string rings =
      format("%d rings %.2f deg apart", sensor.rings, sensor.ring_spacing * 180.0 / std::numbers::pi);
  // A LiDAR's range is its own, not its first scan's: that scan tells how large the place is
  // where the recording starts (a LiDAR that starts in a room sees the hall or the street beyond
  // it later: docs/SLAM.md, "Session 33"). It reaches as far as its rings still lie within
  // map.ring_gap_max of each other on a wall, so that what stands there is one HVoxel and not one
  // per ring: a VLP-16's 2 deg rings 3 m apart at 78 m. Its far walls are what a match leans on
  // where nothing stands near (the parking route's empty side road: docs/SLAM.md, "Session 36").
  // At least the outdoor preset's 25 m (the paper's), at most 100 m (the common spinning LiDARs'
  // specified reach: the farther, the larger the scan window and the tracer's work for the same
  // points). The scan window's dense arrays (a few per scan, 4 bytes a cell) stay within 512 cells
  // each way of the sensor, 1 M cells, for a range chosen here (balm_os0 at --cell 0.1 and 100 m
  // took 208 MB of memory against 53 MB at 25 m; 51.2 m at 0.1 m cells), but never under the 25 m
  // or the 2048 cells (validate()'s rule) a LiDAR had before.
  constexpr double kSpecifiedReach = 100.0;
  constexpr double kWindowCells = 512.0;
  const double cell = p.map.cell_size;
  const double place = p.map.max_range;  // the range the preset was chosen for
  const double floor_reach = outdoor_preset().map.max_range;
  const double ring_reach = slope > 0.0 ? std::floor(p.map.ring_gap_max / slope) : 0.0;
  const double window_reach = std::max(kWindowCells * cell, std::min(floor_reach, 2048.0 * cell));
  const double wanted = std::clamp(ring_reach, floor_reach, kSpecifiedReach);
  double reach = std::min(wanted, window_reach);
  while (std::ceil(reach / cell) > 2048.0) reach = std::nextafter(reach, 0.0);  // validate()'s rule, exactly
  if (is_spinning_lidar(sensor) && !max_range_named && p.map.max_range == preset_params.map.max_range &&
      p.map.max_range < reach) {
    p.map.max_range = reach;
    std::string why;
    if (ring_reach > kSpecifiedReach) {
      why = format("a LiDAR (%s): its rings lie map.ring_gap_max = %g m apart on a wall only beyond the %.0f m the "
                   "common spinning LiDARs reach", rings.c_str(), p.map.ring_gap_max, kSpecifiedReach);
    } else if (ring_reach > floor_reach) {
      why = format("a LiDAR (%s): its rings lie map.ring_gap_max = %g m apart on a wall %.0f m away", rings.c_str(),
                   p.map.ring_gap_max, ring_reach);
    } else {
      why = format("a LiDAR (%s) reaches beyond the room its first scan was taken in", rings.c_str());
    }
    if (reach < wanted) {
      why += format(" (held to %.0f cells each way of the scan window)", std::ceil(reach / cell));
    }
    chosen.push_back({"map.max_range", reach, why});
  }
  const bool gap_unset = !gap_named && p.map.ring_gap_slope == preset_params.map.ring_gap_slope &&
                         p.map.point_distance_threshold == preset_params.map.point_distance_threshold;
  if (is_spinning_lidar(sensor) && gap_unset) {
    // The rings' spread grows with each cell's distance, and so does its gap, so that a far wall
    // is one HVoxel while a near table stays apart from the floor under it. One gap for the whole
    // range could not do both: a VLP-16's 0.87 m at 25 m merged a room's tables with its floor,
    // the preset's 0.4 m split a hall's far walls ring by ring (docs/SLAM.md, "Session 34").
    if (slope > 0.0) {
      p.map.ring_gap_slope = slope;
      const double base = p.map.point_distance_threshold;
      chosen.push_back({"map.ring_gap_slope", slope,
                        format("%s: the height gap is %.2f m near and %.2f m at %.0f m (%g m at most)",
                               rings.c_str(), base,
                               std::max(base, std::min(slope * p.map.max_range, p.map.ring_gap_max)),
                               p.map.max_range, p.map.ring_gap_max)});
    }
  } else if (!is_spinning_lidar(sensor) && sensor.rings > 0 && gap_unset) {
    // Rows that read as rings but not all around (the simulated Kinect's beyond 5 m: docs/SLAM.md,
    // "Session 33"): one gap, at the range the preset was chosen for, as before session 34.
    const double gap = sensor.ring_spacing * place;
    const double value = std::clamp(gap, preset_params.map.point_distance_threshold, 1.0);
    const std::string reason = format("%s: %.2f m between rings at the %.0f m range %s", rings.c_str(), gap, place,
                                      place == p.map.max_range ? "limit" : "of the preset");
    const double rounded = std::round(value * 100.0) / 100.0;
    if (rounded != p.map.point_distance_threshold) {
      p.map.point_distance_threshold = rounded;
      chosen.push_back({"map.point_distance_threshold", p.map.point_distance_threshold, reason});
    }
  }
  return chosen;
}

}  // namespace hmap
