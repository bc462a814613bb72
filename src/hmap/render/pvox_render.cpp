#include "hmap/render/pvox_render.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "hmap/render/render.hpp"

namespace hmap::render {

namespace {

std::vector<pvox::VoxelView> visible(const pvox::VoxelMap& map, const PvoxView& view) {
  auto voxels = map.occupied(view.threshold);
  if (view.clip) std::erase_if(voxels, [&](const pvox::VoxelView& v) { return !view.clip->contains(v.centre); });
  return voxels;
}

Eigen::AlignedBox3d bounds_of(const std::vector<pvox::VoxelView>& voxels, double edge) {
  Eigen::AlignedBox3d box;
  for (const auto& v : voxels) {
    box.extend(v.centre - Eigen::Vector3d::Constant(0.5 * edge));
    box.extend(v.centre + Eigen::Vector3d::Constant(0.5 * edge));
  }
  return box;
}

/// 2nd and 98th percentile of the voxel heights.
std::pair<double, double> height_range(const std::vector<pvox::VoxelView>& voxels) {
  std::vector<double> z;
  z.reserve(voxels.size());
  for (const auto& v : voxels) z.push_back(v.centre.z());
  std::sort(z.begin(), z.end());
  const double lo = z[z.size() / 50];
  const double hi = z[z.size() - 1 - z.size() / 50];
  return {lo, hi > lo ? hi : lo + 1.0};
}

void shade(std::uint8_t& c, double f) { c = static_cast<std::uint8_t>(std::clamp(std::lround(c * f), 0L, 255L)); }

void fill_quad(RgbImage& img, const std::array<Eigen::Vector2d, 4>& q, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  double x0 = q[0].x(), x1 = q[0].x(), y0 = q[0].y(), y1 = q[0].y();
  for (const auto& p : q) {
    x0 = std::min(x0, p.x());
    x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y());
    y1 = std::max(y1, p.y());
  }
  const int ix0 = std::max(0, static_cast<int>(std::floor(x0)));
  const int ix1 = std::min(img.width - 1, static_cast<int>(std::ceil(x1)));
  const int iy0 = std::max(0, static_cast<int>(std::floor(y0)));
  const int iy1 = std::min(img.height - 1, static_cast<int>(std::ceil(y1)));
  for (int y = iy0; y <= iy1; ++y) {
    for (int x = ix0; x <= ix1; ++x) {
      const Eigen::Vector2d p(x + 0.5, y + 0.5);
      int sign = 0;
      bool inside = true;
      for (int k = 0; k < 4 && inside; ++k) {
        const Eigen::Vector2d a = q[static_cast<std::size_t>(k)];
        const Eigen::Vector2d b2 = q[static_cast<std::size_t>((k + 1) % 4)];
        const double cross = (b2.x() - a.x()) * (p.y() - a.y()) - (b2.y() - a.y()) * (p.x() - a.x());
        const int s = cross > 1e-12 ? 1 : cross < -1e-12 ? -1 : 0;
        if (s != 0) {
          if (sign != 0 && s != sign) inside = false;
          sign = s;
        }
      }
      if (inside) img.set(x, y, r, g, b);
    }
  }
}

/// A scale bar in a panel to the right of a top-down picture of `m_per_px` metres per pixel.
void draw_scale(RgbImage& img, double m_per_px) {
  TopViewport viewport;
  viewport.m_per_px = m_per_px;
  viewport.width = img.width;
  viewport.height = img.height;
  draw_legend_and_scale(img, viewport, {});
}

void draw_segment(RgbImage& img, double x0, double y0, double x1, double y1, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  const int n = static_cast<int>(std::ceil(std::max(std::abs(x1 - x0), std::abs(y1 - y0)))) + 1;
  for (int k = 0; k <= n; ++k) {
    const double t = static_cast<double>(k) / n;
    const int x = static_cast<int>(std::lround(x0 + t * (x1 - x0)));
    const int y = static_cast<int>(std::lround(y0 + t * (y1 - y0)));
    if (x >= 0 && y >= 0 && x < img.width && y < img.height) img.set(x, y, r, g, b);
  }
}

}  // namespace

RgbImage render_pvox_top(const pvox::VoxelMap& map, const PvoxView& view) {
  check_max_pixels(view.max_pixels);
  const auto voxels = visible(map, view);
  if (voxels.empty()) return RgbImage(64, 64, 0);
  const double e = map.edge();
  const Eigen::AlignedBox3d box = bounds_of(voxels, e);
  const double span = std::max(box.sizes().x(), box.sizes().y());
  const double m_per_px = span / view.max_pixels;
  const int w = std::max(1, static_cast<int>(std::ceil(box.sizes().x() / m_per_px)));
  const int h = std::max(1, static_cast<int>(std::ceil(box.sizes().y() / m_per_px)));
  RgbImage img(w, h, 0);
  std::vector<double> top(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), -std::numeric_limits<double>::infinity());
  const auto [z_lo, z_hi] = height_range(voxels);
  for (const auto& v : voxels) {
    const int x0 = static_cast<int>(std::floor((v.centre.x() - 0.5 * e - box.min().x()) / m_per_px));
    const int x1 = static_cast<int>(std::floor((v.centre.x() + 0.5 * e - box.min().x()) / m_per_px));
    const int y0 = static_cast<int>(std::floor((box.max().y() - v.centre.y() - 0.5 * e) / m_per_px));
    const int y1 = static_cast<int>(std::floor((box.max().y() - v.centre.y() + 0.5 * e) / m_per_px));
    std::uint8_t r = 0, g = 0, b = 0;
    height_colour((v.centre.z() - z_lo) / (z_hi - z_lo), r, g, b);
    const double f = 0.45 + 0.55 * (v.probability - view.threshold) / (1.0 - view.threshold);
    shade(r, f);
    shade(g, f);
    shade(b, f);
    for (int y = std::max(0, y0); y < std::min(h, y1); ++y) {
      for (int x = std::max(0, x0); x < std::min(w, x1); ++x) {
        double& t = top[static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x)];
        if (v.centre.z() <= t) continue;
        t = v.centre.z();
        // A thin dark outline shows the voxel grid.
        const bool rim = x == x0 || y == y0;
        img.set(x, y, rim ? static_cast<std::uint8_t>(r / 2) : r, rim ? static_cast<std::uint8_t>(g / 2) : g,
                rim ? static_cast<std::uint8_t>(b / 2) : b);
      }
    }
  }
  draw_scale(img, m_per_px);
  return img;
}

RgbImage render_pvox_iso(const pvox::VoxelMap& map, const PvoxView& view) {
  check_max_pixels(view.max_pixels);
  auto voxels = visible(map, view);
  if (voxels.empty()) return RgbImage(64, 64, 0);
  const double e = map.edge();
  // Viewer in the south-west, above: looking along d; screen right r, screen up u.
  const double elevation = 35.0 * std::acos(-1.0) / 180.0;
  const Eigen::Vector3d d =
      Eigen::Vector3d(std::cos(elevation) / std::sqrt(2.0), std::cos(elevation) / std::sqrt(2.0), -std::sin(elevation));
  const Eigen::Vector3d r = Eigen::Vector3d(1.0, -1.0, 0.0).normalized();
  const Eigen::Vector3d u = r.cross(d).normalized() * -1.0;
  const Eigen::Vector3d up = u.z() < 0 ? Eigen::Vector3d(-u) : u;
  Eigen::AlignedBox2d screen;
  for (const auto& v : voxels) {
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3d p = v.centre + 0.5 * e * Eigen::Vector3d(c & 1 ? 1 : -1, c & 2 ? 1 : -1, c & 4 ? 1 : -1);
      screen.extend(Eigen::Vector2d(r.dot(p), up.dot(p)));
    }
  }
  const double scale = view.max_pixels / std::max(screen.sizes().x(), screen.sizes().y());
  const int w = std::max(1, static_cast<int>(std::ceil(screen.sizes().x() * scale)) + 2);
  const int h = std::max(1, static_cast<int>(std::ceil(screen.sizes().y() * scale)) + 2);
  RgbImage img(w, h, 255);
  const auto px = [&](const Eigen::Vector3d& p) {
    return Eigen::Vector2d((r.dot(p) - screen.min().x()) * scale + 1.0, (screen.max().y() - up.dot(p)) * scale + 1.0);
  };
  // Painter's algorithm: far voxels first.
  std::sort(voxels.begin(), voxels.end(), [&](const auto& a, const auto& b) { return d.dot(a.centre) > d.dot(b.centre); });
  const auto [z_lo, z_hi] = height_range(voxels);
  const double h2 = 0.5 * e;
  for (const auto& v : voxels) {
    std::uint8_t cr = 0, cg = 0, cb = 0;
    height_colour((v.centre.z() - z_lo) / (z_hi - z_lo), cr, cg, cb);
    const Eigen::Vector3d c = v.centre;
    const auto corner = [&](double sx, double sy, double sz) { return px(c + h2 * Eigen::Vector3d(sx, sy, sz)); };
    // The faces turned to the viewer: −x, −y and +z.
    const std::array<Eigen::Vector2d, 4> fx = {corner(-1, -1, -1), corner(-1, 1, -1), corner(-1, 1, 1), corner(-1, -1, 1)};
    const std::array<Eigen::Vector2d, 4> fy = {corner(-1, -1, -1), corner(1, -1, -1), corner(1, -1, 1), corner(-1, -1, 1)};
    const std::array<Eigen::Vector2d, 4> fz = {corner(-1, -1, 1), corner(1, -1, 1), corner(1, 1, 1), corner(-1, 1, 1)};
    const auto sh = [](std::uint8_t c0, double f) { return static_cast<std::uint8_t>(std::clamp(std::lround(c0 * f), 0L, 255L)); };
    fill_quad(img, fx, sh(cr, 0.62), sh(cg, 0.62), sh(cb, 0.62));
    fill_quad(img, fy, sh(cr, 0.78), sh(cg, 0.78), sh(cb, 0.78));
    fill_quad(img, fz, cr, cg, cb);
  }
  return img;
}

RgbImage render_pvox_gradient(const pvox::VoxelMap& map, const PvoxView& view, double z, int arrow_step_px) {
  check_max_pixels(view.max_pixels);
  auto voxels = map.voxels();
  if (view.clip) std::erase_if(voxels, [&](const pvox::VoxelView& v) { return !view.clip->contains(v.centre); });
  if (voxels.empty()) return RgbImage(64, 64, 0);
  const Eigen::AlignedBox3d box = bounds_of(voxels, map.edge());
  const double span = std::max(box.sizes().x(), box.sizes().y());
  const double m_per_px = span / view.max_pixels;
  const int w = std::max(1, static_cast<int>(std::ceil(box.sizes().x() / m_per_px)));
  const int h = std::max(1, static_cast<int>(std::ceil(box.sizes().y() / m_per_px)));
  RgbImage img(w, h, 0);
  const auto world = [&](double x, double y) {
    return Eigen::Vector3d(box.min().x() + (x + 0.5) * m_per_px, box.max().y() - (y + 0.5) * m_per_px, z);
  };
  double max_gradient = 1e-9;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const pvox::FieldSample f = map.field_at(world(x, y));
      const auto grey = static_cast<std::uint8_t>(std::lround(255.0 * std::clamp(f.probability, 0.0, 1.0)));
      // Occupied shades toward red so obstacles stand out from the grey of unknown space.
      if (f.probability > 0.5) {
        img.set(x, y, grey, static_cast<std::uint8_t>(grey * (1.0 - f.probability)), static_cast<std::uint8_t>(grey * (1.0 - f.probability)));
      } else {
        img.set(x, y, grey, grey, grey);
      }
      max_gradient = std::max(max_gradient, f.gradient.head<2>().norm());
    }
  }
  const int step = std::max(4, arrow_step_px);
  for (int y = step / 2; y < h; y += step) {
    for (int x = step / 2; x < w; x += step) {
      const pvox::FieldSample f = map.field_at(world(x, y));
      const Eigen::Vector2d g = -f.gradient.head<2>();
      if (g.norm() < 0.02 * max_gradient) continue;
      // Image y grows downwards: flip the world y component.
      const Eigen::Vector2d a = Eigen::Vector2d(g.x(), -g.y()) / max_gradient * (0.9 * step);
      const double len = std::max(a.norm(), 3.0);
      const Eigen::Vector2d dir = a / a.norm() * len;
      const double x1 = x + dir.x(), y1 = y + dir.y();
      draw_segment(img, x, y, x1, y1, 40, 140, 255);
      const Eigen::Vector2d back = -dir / len * 4.0;
      const Eigen::Vector2d side(-back.y(), back.x());
      draw_segment(img, x1, y1, x1 + back.x() + 0.6 * side.x(), y1 + back.y() + 0.6 * side.y(), 40, 140, 255);
      draw_segment(img, x1, y1, x1 + back.x() - 0.6 * side.x(), y1 + back.y() - 0.6 * side.y(), 40, 140, 255);
    }
  }
  draw_scale(img, m_per_px);
  return img;
}

PvoxView bulk_view(const pvox::VoxelMap& map) {
  PvoxView view;
  const auto occupied = map.occupied();
  if (occupied.size() > 100) {
    Eigen::Vector3d lo;
    Eigen::Vector3d hi;
    for (int a = 0; a < 3; ++a) {
      std::vector<double> c;
      c.reserve(occupied.size());
      for (const auto& v : occupied) c.push_back(v.centre[a]);
      std::sort(c.begin(), c.end());
      lo[a] = c[c.size() / 50] - map.edge();
      hi[a] = c[c.size() - 1 - c.size() / 50] + map.edge();
    }
    view.clip = Eigen::AlignedBox3d(lo, hi);
  }
  return view;
}

}  // namespace hmap::render
