#include "hmap/slam/hvoxel_metric.hpp"

#include <gtest/gtest.h>

#include <random>

namespace hmap::slam {
namespace {

constexpr float kTiny = 1e-4F;  // min_height that leaves the hand-made intervals as they are

TEST(HVoxelMetric, IntervalIoUByHand) {
  EXPECT_FLOAT_EQ(interval_iou({0.0F, 1.0F}, {0.5F, 2.0F}), 0.5F / 2.0F);
  EXPECT_FLOAT_EQ(interval_iou({0.0F, 1.0F}, {0.0F, 1.0F}), 1.0F);
  EXPECT_FLOAT_EQ(interval_iou({0.0F, 1.0F}, {2.0F, 3.0F}), 0.0F);
  EXPECT_FLOAT_EQ(interval_iou({1.0F, 1.0F}, {1.0F, 1.0F}), 0.0F);  // no height: no volume
}

TEST(HVoxelMetric, WideningKeepsTheCentre) {
  const Interval w = widened({1.0F, 1.0F}, 0.2F);
  EXPECT_FLOAT_EQ(w.z_min, 0.9F);
  EXPECT_FLOAT_EQ(w.z_max, 1.1F);
  const Interval tall = widened({0.0F, 3.0F}, 0.2F);
  EXPECT_EQ(tall, (Interval{0.0F, 3.0F}));
}

TEST(HVoxelMetric, Eq9SumsOverTheHVoxelsOfTheLayer) {
  // Layer [0, 2]; the column holds [-0.5, 0.5], [1.5, 3] and [4, 5] (outside the layer).
  const std::vector<HVoxel> column = {{-0.5F, 0.5F, 10, 1}, {1.5F, 3.0F, 10, 1}, {4.0F, 5.0F, 10, 1}};
  const LayerMatch m = match_layer({0.0F, 2.0F}, column, kTiny);
  ASSERT_TRUE(m.present);
  // Σ ∩ = 0.5 + 0.5; Σ ∪ = (2 + 1 − 0.5) + (2 + 1.5 − 0.5) = 5.5.
  EXPECT_FLOAT_EQ(m.iou, 1.0F / 5.5F);
  EXPECT_EQ(m.hull, (Interval{-0.5F, 3.0F}));
  EXPECT_FALSE(match_layer({3.2F, 3.8F}, column, kTiny).present);
  EXPECT_FALSE(match_layer({0.0F, 1.0F}, {}, kTiny).present);
}

TEST(HVoxelMetric, Eq10And11ByHand) {
  const float s = 0.2F;
  // F00 = 0, F10 = 1, F01 = 0, F11 = 1: a ramp along x.
  MetricSample m = bilinear({0.0F, 1.0F, 0.0F, 1.0F}, 0.25F, 0.5F, s);
  EXPECT_FLOAT_EQ(m.value, 0.25F);
  EXPECT_FLOAT_EQ(m.gradient.x(), 1.0F / s);
  EXPECT_FLOAT_EQ(m.gradient.y(), 0.0F);
  // F00 = 0.2, F10 = 0.4, F01 = 0.6, F11 = 1.0 at a = 0.5, b = 0.25:
  // value = 0.25·(0.5·1.0 + 0.5·0.6) + 0.75·(0.5·0.4 + 0.5·0.2) = 0.2 + 0.225 = 0.425
  // ∂x = (0.25·(1.0 − 0.6) + 0.75·(0.4 − 0.2)) / s = 0.25 / s
  // ∂y = (0.5·(1.0 − 0.4) + 0.5·(0.6 − 0.2)) / s = 0.5 / s
  m = bilinear({0.2F, 0.4F, 0.6F, 1.0F}, 0.5F, 0.25F, s);
  EXPECT_NEAR(m.value, 0.425F, 1e-6F);
  EXPECT_NEAR(m.gradient.x(), 0.25F / s, 1e-5F);
  EXPECT_NEAR(m.gradient.y(), 0.5F / s, 1e-5F);
  // At the corners the value is the corner's F.
  EXPECT_FLOAT_EQ(bilinear({0.2F, 0.4F, 0.6F, 1.0F}, 0.0F, 0.0F, s).value, 0.2F);
  EXPECT_FLOAT_EQ(bilinear({0.2F, 0.4F, 0.6F, 1.0F}, 1.0F, 1.0F, s).value, 1.0F);
}

TEST(HVoxelMetric, GradientMatchesFiniteDifferences) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> unit(0.0F, 1.0F);
  std::uniform_real_distribution<float> inner(0.05F, 0.95F);
  const float s = 0.25F;
  for (int trial = 0; trial < 200; ++trial) {
    const std::array<float, 4> F{unit(rng), unit(rng), unit(rng), unit(rng)};
    const float a = inner(rng);
    const float b = inner(rng);
    const float h = 1e-3F;  // in cells
    const MetricSample m = bilinear(F, a, b, s);
    const float dx = (bilinear(F, a + h, b, s).value - bilinear(F, a - h, b, s).value) / (2.0F * h * s);
    const float dy = (bilinear(F, a, b + h, s).value - bilinear(F, a, b - h, s).value) / (2.0F * h * s);
    EXPECT_NEAR(m.gradient.x(), dx, 2e-2F);
    EXPECT_NEAR(m.gradient.y(), dy, 2e-2F);
  }
}

Params small_params() {
  Params p;
  p.map.cell_size = 0.2;
  p.slam.min_layer_height = 1e-4;
  p.slam.idw_weight = 0.5;
  p.slam.idw_power = 2.0;
  p.slam.interpolation_window = 3;
  return p;
}

TEST(HVoxelMetric, Eq12InterpolatesMissingNeighboursByHand) {
  const Params p = small_params();
  HMap map(p);
  map.column_for_update({0, 0}).push_back({0.0F, 2.0F, 10, 1});
  map.column_for_update({2, 0}).push_back({0.0F, 1.0F, 10, 1});
  LocalMapView view;
  view.reset(map, {0, 0}, 10);
  const LayerInterpolator interp(p);
  const std::array<float, 4> F = interp.corner_values(view, {0.0F, 2.0F}, {0, 0});
  EXPECT_FLOAT_EQ(F[0], 1.0F);  // (0, 0) holds the layer itself
  // (1, 0): (0, 0) and (2, 0) both one cell away, equal weights: v' = [0, 1.5], IoU 0.75, × 0.5.
  EXPECT_NEAR(F[1], 0.375F, 1e-5F);
  // (0, 1): only (0, 0) in its window: v' = [0, 2], IoU 1, × 0.5.
  EXPECT_NEAR(F[2], 0.5F, 1e-5F);
  // (1, 1): (0, 0) and (2, 0) both diagonal: v' = [0, 1.5] again.
  EXPECT_NEAR(F[3], 0.375F, 1e-5F);
  // Unequal distances: cell (3, 0) has (2, 0) at one cell, nothing else within its window.
  const std::array<float, 4> far = interp.corner_values(view, {0.0F, 2.0F}, {3, 0});
  EXPECT_NEAR(far[0], 0.5F * 0.5F, 1e-5F);  // v' = [0, 1]: IoU 0.5
  EXPECT_FLOAT_EQ(far[1], 0.0F);           // (4, 0): nothing around
}

TEST(HVoxelMetric, Eq12WeightsByInverseDistance) {
  Params p = small_params();
  HMap map(p);
  // Around (0, 0): [0, 1] one cell away at (1, 0) (w = 1/s²), [0, 3] diagonal at (-1, -1) (w = 1/(2s²)).
  map.column_for_update({1, 0}).push_back({0.0F, 1.0F, 10, 1});
  map.column_for_update({-1, -1}).push_back({0.0F, 3.0F, 10, 1});
  LocalMapView view;
  view.reset(map, {0, 0}, 10);
  const LayerInterpolator interp(p);
  const std::array<float, 4> F = interp.corner_values(view, {0.0F, 3.0F}, {0, 0});
  // v' z_max = (1·1 + 0.5·3) / 1.5 = 5/3; IoU with [0, 3] = 5/9; × 0.5.
  EXPECT_NEAR(F[0], 0.5F * 5.0F / 9.0F, 1e-5F);
}

TEST(HVoxelMetric, LocalMapViewAgreesWithTheMap) {
  const Params p = small_params();
  HMap map(p);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> cell(-40, 40);
  for (int k = 0; k < 300; ++k) {
    const auto z = static_cast<float>(k % 7);
    map.column_for_update({cell(rng), cell(rng)}).merge({z, z + 0.5F, 10, 1}, 0.0F, p.map);
  }
  LocalMapView view;
  view.reset(map, {5, -3}, 20);  // part of the map lies outside: looked up through the map
  for (int i = -45; i <= 45; ++i) {
    for (int j = -45; j <= 45; ++j) {
      const auto expected = map.column(CellKey{i, j}).hvoxels();
      const auto got = view.column({i, j});
      ASSERT_EQ(got.size(), expected.size()) << i << " " << j;
      if (!got.empty()) {
        EXPECT_EQ(got.data(), expected.data());
      }
    }
  }
}

TEST(HVoxelMetric, MetricGradientOnAMapMatchesFiniteDifferences) {
  // M_H along a line crossing a wall of HVoxels, within one cell square (F cached there).
  const Params p = small_params();
  HMap map(p);
  for (int j = -5; j <= 5; ++j) map.column_for_update({0, j}).push_back({0.0F, 2.0F, 10, 1});
  LocalMapView view;
  view.reset(map, {0, 0}, 10);
  const LayerInterpolator interp(p);
  const float s = 0.2F;
  for (float x : {0.13F, 0.2F, 0.27F, -0.05F, 0.33F}) {
    const float y = 0.061F;
    auto value_at = [&](float qx, float qy) {
      const float u = qx / s - 0.5F;
      const float w = qy / s - 0.5F;
      const CellKey base{static_cast<std::int32_t>(std::floor(u)), static_cast<std::int32_t>(std::floor(w))};
      const auto F = interp.corner_values(view, {0.0F, 2.0F}, base);
      return bilinear(F, u - std::floor(u), w - std::floor(w), s);
    };
    const MetricSample m = value_at(x, y);
    const float h = 1e-3F;
    EXPECT_NEAR(m.gradient.x(), (value_at(x + h, y).value - value_at(x - h, y).value) / (2 * h), 1e-2F) << x;
    EXPECT_NEAR(m.gradient.y(), (value_at(x, y + h).value - value_at(x, y - h).value) / (2 * h), 1e-2F) << x;
    // The wall cell's centre is x = 0.1: M_H peaks there.
    EXPECT_LE(m.value, value_at(0.1F, y).value + 1e-6F);
  }
}

}  // namespace
}  // namespace hmap::slam
