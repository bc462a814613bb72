// The page in a real browser: headless Chromium (Debian's chromium) on `hmap view` of a small
// room, driven by browser_check.mjs over the DevTools protocol. Checks: no console error; the
// canvas is not blank and shows, at the room's table, floor and walls, the colours of their
// heights; unticking the HVoxels layer takes them away; a click on the table returns the column
// the C++ API holds. The same page on a live `hmap slam --view` follows the run. Skips with a
// message where Chromium or Node cannot run.

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "hmap/io/poses.hpp"
#include "hmap/view/map_scene.hpp"
#include "serve/test_map.hpp"
#include "serve/view_process.hpp"

namespace hmap::test {
namespace {

namespace fs = std::filesystem;

std::string find_program(const char* env, std::initializer_list<const char*> paths) {
  if (const char* e = std::getenv(env); e != nullptr && *e != '\0') return e;
  for (const char* p : paths) {
    if (::access(p, X_OK) == 0) return p;
  }
  return {};
}

std::string run_output(const std::string& cmd) {
  std::string out;
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (pipe == nullptr) return out;
  std::array<char, 65536> buf{};
  for (std::size_t n; (n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0;) out.append(buf.data(), n);
  ::pclose(pipe);
  return out;
}

int colour_distance(const nlohmann::json& sample, const std::array<std::uint8_t, 4>& c) {
  int d = 0;
  for (int k = 0; k < 3; ++k) d = std::max(d, std::abs(sample[2 + k].get<int>() - c[k]));
  return d;
}

/// Chromium and a Node with a WebSocket client, or why not.
struct Tools {
  std::string chromium, node, missing;
};

Tools find_tools() {
  Tools t;
  t.chromium = find_program("HMAP_CHROMIUM", {"/usr/bin/chromium", "/usr/bin/chromium-browser"});
  t.node = find_program("HMAP_NODE", {"/usr/bin/node", "/usr/local/bin/node"});
  if (t.chromium.empty() || t.node.empty()) {
    t.missing = "no chromium or node here (Debian: apt-get install chromium nodejs)";
  } else if (std::system((t.node + " --experimental-websocket --no-warnings -e \"process.exit(typeof WebSocket === 'function' ? 0 : 3)\" "
                          ">/dev/null 2>&1").c_str()) != 0) {
    // The DevTools client is Node's own WebSocket (Node >= 20.10 with the flag, 22 without).
    t.missing = t.node + " has no WebSocket client (Node >= 20.10 needed)";
  }
  return t;
}

/// browser_check.mjs on `url`; its JSON, or a failure with what it printed.
nlohmann::json check_in_browser(const Tools& t, const std::string& url, const fs::path& dir, const nlohmann::json& points) {
  const std::string out = run_output(t.node + " --experimental-websocket --no-warnings " + HMAP_BROWSER_SCRIPT + " " + t.chromium +
                                     " " + url + " " + dir.string() + " '" + points.dump() + "'");
  try {
    return nlohmann::json::parse(out);
  } catch (const std::exception&) {
    return {{"error", "browser_check.mjs printed: " + out}};
  }
}

TEST(Browser, ThePageShowsTheMapAndAnswersClicks) {
  const auto t0 = std::chrono::steady_clock::now();
  const Tools tools = find_tools();
  if (!tools.missing.empty()) GTEST_SKIP() << tools.missing;

  const fs::path dir = fs::temp_directory_path() / ("hmap_browser_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  save_room(dir / "room.hmap");
  ViewProcess view({(dir / "room.hmap").string(), "--port", "0"});
  ASSERT_FALSE(view.url().empty()) << view.output();

  // What the page must show, from the C++ side: the top box of three cells seen from above.
  MapFile file = load_map_file(dir / "room.hmap");
  const view::MapScene scene(std::move(file.map), {}, std::nullopt, {});
  struct Probe {
    double x, y;
  };
  // The table (cell (10, 6)), the floor (same HVoxel as under the table), the west wall.
  const std::vector<Probe> probes{{2.6, 1.6}, {4.9, 3.1}, {0.1, 2.1}};
  nlohmann::json points = nlohmann::json::array();
  std::vector<std::array<std::uint8_t, 4>> expected;
  for (const Probe& p : probes) {
    const ColumnView c = scene.map().column(p.x, p.y);
    ASSERT_FALSE(c.empty());
    const HVoxel& top = c[c.size() - 1];
    const Eigen::Vector2d centre = scene.map().cell_center(*scene.map().key_of(p.x, p.y));
    points.push_back({centre.x(), centre.y(), top.z_max});
    expected.push_back(view::height_colour(0.5F * (top.z_min + top.z_max), scene.z_low(), scene.z_high()));
  }

  const nlohmann::json r = check_in_browser(tools, view.url(), dir, points);
  if (r.contains("skip")) GTEST_SKIP() << r["skip"].get<std::string>();
  ASSERT_FALSE(r.contains("error")) << r.dump(1);
  EXPECT_TRUE(r["console_errors"].empty()) << r["console_errors"].dump(1);

  // Not blank, and the colours of the heights where the map is.
  EXPECT_GT(r["distinct_colours"].get<int>(), 4) << r.dump();
  ASSERT_EQ(r["with_hvoxels"].size(), probes.size());
  for (std::size_t k = 0; k < probes.size(); ++k) {
    EXPECT_LE(colour_distance(r["with_hvoxels"][k], expected[k]), 3) << "probe " << k << ": " << r["with_hvoxels"][k].dump();
    // The layer unticked: that colour is gone from there.
    EXPECT_GT(colour_distance(r["without_hvoxels"][k], expected[k]), 40) << "probe " << k << ": " << r["without_hvoxels"][k].dump();
  }
  // The height slider at 0.5 m cuts the table top (0.7-0.75 m) away: the floor under it shows
  // (the ground patches over it hidden for this).
  EXPECT_LE(colour_distance(r["with_cut"][0], expected[1]), 3) << r["with_cut"][0].dump();
  EXPECT_GT(colour_distance(r["with_cut"][0], expected[0]), 40) << r["with_cut"][0].dump();
  // The background outside the room is the page's clear colour (0x1d2024).
  EXPECT_EQ(r["background"], nlohmann::json({0x1d, 0x20, 0x24}));

  // The clicked cell's column is the C++ API's.
  ASSERT_TRUE(r["column"].is_object()) << r.dump();
  const CellKey key = *scene.map().key_of(probes[0].x, probes[0].y);
  EXPECT_EQ(r["column"]["cell"], nlohmann::json({key.i, key.j}));
  const ColumnView c = scene.map().column(key);
  ASSERT_EQ(r["column"]["hvoxels"].size(), c.size());
  for (std::size_t k = 0; k < c.size(); ++k) {
    const nlohmann::json& h = r["column"]["hvoxels"][k];
    EXPECT_EQ(h["z_min"].get<float>(), c[k].z_min);
    EXPECT_EQ(h["z_max"].get<float>(), c[k].z_max);
    EXPECT_EQ(h["count"].get<float>(), c[k].count);
    EXPECT_EQ(h["density"].get<float>(), c[k].density);
  }
  EXPECT_EQ(nlohmann::json::parse(r["column_panel"].get<std::string>()), r["column"]);

  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("browser: page open in %d ms, %d HVoxels, %d boxes drawn, %.1f frames/s (SwiftShader), %.1f s in all\n",
              r["open_ms"].get<int>(), r["info"]["hvoxels"].get<int>(), r["boxes_drawn"].get<int>(), r["fps"].get<double>(),
              seconds);
  EXPECT_LT(seconds, 30.0);
  EXPECT_EQ(view.stop(), 0) << view.output();
  fs::remove_all(dir);
}

// A map of several view tiles as a user opens it (oblique view, shaded): tiles arrive, are drawn
// at their level of detail, the camera turns. HMAP_VIEW_BENCH_CELLS=N makes the room N × N cells
// (the README's measurements); by default 100 × 100, about 14,000 HVoxels in 4 view tiles.
TEST(Browser, OpensAMapOfManyTiles) {
  const Tools tools = find_tools();
  if (!tools.missing.empty()) GTEST_SKIP() << tools.missing;
  const char* env = std::getenv("HMAP_VIEW_BENCH_CELLS");
  const int side = env != nullptr && *env != '\0' ? std::atoi(env) : 100;
  const fs::path dir = fs::temp_directory_path() / ("hmap_browser_big_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  save_room(dir / "room.hmap", side, side);
  ViewProcess view({(dir / "room.hmap").string(), "--port", "0"});
  ASSERT_FALSE(view.url().empty()) << view.output();
  const nlohmann::json r = check_in_browser(tools, view.url(), dir, nlohmann::json::array());
  const double server_cpu_s = view.cpu_seconds();  // the frames/s measurement asks nothing of it
  if (r.contains("skip")) GTEST_SKIP() << r["skip"].get<std::string>();
  ASSERT_FALSE(r.contains("error")) << r.dump(1);
  EXPECT_TRUE(r["console_errors"].empty()) << r["console_errors"].dump(1);
  const int hvoxels = r["info"]["hvoxels"].get<int>();
  EXPECT_GT(r["info"]["tiles"].get<int>(), 1);
  EXPECT_GT(r["boxes_drawn"].get<int>(), 0);
  EXPECT_LE(r["boxes_drawn"].get<int>(), hvoxels);
  EXPECT_GT(r["fps"].get<double>(), 0.0);
  // Where the opening went: the tile requests (waiting for the server's first byte: encoding and
  // queueing; then the transfer), building meshes from their bytes, GL.
  int tile_requests = 0;
  double tile_bytes = 0.0, tile_wait_ms = 0.0, tile_transfer_ms = 0.0, tiles_first = 1e9, tiles_last = 0.0;
  for (const nlohmann::json& e : r["resource_timing"]) {
    if (e[0].get<std::string>().rfind("/api/tile", 0) != 0) continue;
    ++tile_requests;
    tile_bytes += e[4].get<double>();
    tile_wait_ms += e[2].get<double>() - e[1].get<double>();
    tile_transfer_ms += e[3].get<double>() - e[2].get<double>();
    tiles_first = std::min(tiles_first, e[1].get<double>());
    tiles_last = std::max(tiles_last, e[3].get<double>());
  }
  const nlohmann::json& pt = r["page_timing"];
  std::printf("browser, %d x %d cells: %d HVoxels in %d view tiles, page open in %d ms (Chromium up in %d ms), "
              "%d boxes drawn, %.1f frames/s turning (SwiftShader); in the page: three.js evaluated at %.0f ms, WebGL up at %.0f ms, "
              "map asked at %.0f ms, summary at %.0f ms, tiles drawn at %.0f ms; %d tile requests, %.1f MB, from %.0f to %.0f ms, waiting "
              "%.0f ms (queued in the browser included) and transferring %.0f ms summed over them; meshes built in %.0f ms (the last at %.0f ms), tiles chosen "
              "%d times in %.0f ms, %d renders in %.0f ms; CPU to the first frame: server %.2f s, Chromium %.2f s\n",
              side, side, hvoxels, r["info"]["tiles"].get<int>(), r["open_ms"].get<int>(), r["chromium_ms"].get<int>(),
              r["boxes_drawn"].get<int>(), r["fps"].get<double>(), pt["three"].get<double>(), pt["webgl"].get<double>(), pt["module"].get<double>(), pt["info"].get<double>(),
              pt["drawn"].get<double>(), tile_requests, tile_bytes / 1e6, tiles_first, tiles_last, tile_wait_ms, tile_transfer_ms,
              pt["meshMs"].get<double>(), pt["lastMeshAt"].get<double>(), pt["updates"].get<int>(), pt["updateMs"].get<double>(), pt["renders"].get<int>(), pt["renderMs"].get<double>(), server_cpu_s,
              r["chromium_cpu_s"].get<double>());
  EXPECT_EQ(view.stop(), 0) << view.output();
  fs::remove_all(dir);
}

// hmap slam --view as a user watches it: Chromium is up first, then the run starts and the page is
// opened on the URL it prints; what the page shows is sampled until the run is done and drawn.
// The map and the path must grow on the page while the scans come in, the progress advance, and
// the last map drawn be the saved one with a pose per scan. The live view sends a map at most once
// a second and the page takes a second or two to start, so the run is long enough to be seen:
// 280 simulated VLP-16 sweeps of the parking lot (--sweep: deskewed, about 20 ms of SLAM each).
TEST(Browser, FollowsALiveSlamRun) {
  const Tools tools = find_tools();
  if (!tools.missing.empty()) GTEST_SKIP() << tools.missing;
  const fs::path dir = fs::temp_directory_path() / ("hmap_browser_live_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string sim = run_output(hmap_bin() + " simulate --scene parking --sensor vlp16 --sweep --frames 280 --out " + (dir / "sim").string() + " 2>&1");
  ASSERT_TRUE(fs::exists(dir / "sim" / "poses.txt")) << sim;
  const int kLiveScans = static_cast<int>(read_poses(dir / "sim" / "poses.txt").size());
  ASSERT_GT(kLiveScans, 10) << sim;

  const std::string cmd = tools.node + " --experimental-websocket --no-warnings " + HMAP_BROWSER_SCRIPT + " " + tools.chromium +
                          " --live " + dir.string() + " " + hmap_bin() + " slam --kitti " + (dir / "sim").string() + " --out " +
                          (dir / "slam").string() + " --view --view-port 0";
  // The maps drawn while the run went on: samples with the scan progress, nothing pending, a new version.
  const auto maps_drawn = [](const nlohmann::json& samples) {
    std::size_t n = 0;
    std::string version;
    for (const nlohmann::json& s : samples) {
      int scan = 0, of = 0;
      if (std::sscanf(s["progress"].get<std::string>().c_str(), "scan %d of %d", &scan, &of) != 2 || s["busy"].get<bool>()) continue;
      if (s["version"].dump() != version) ++n;
      version = s["version"].dump();
    }
    return n;
  };
  // A software-GL page on a machine busy with other work may draw the first map only as the run
  // ends: then the same run is followed once more (a page that never updates fails both).
  nlohmann::json r;
  for (int attempt = 0; attempt < 2; ++attempt) {
    std::error_code ec;
    fs::remove_all(dir / "slam", ec);
    const std::string out = run_output(cmd);
    try {
      r = nlohmann::json::parse(out);
    } catch (const std::exception&) {
      FAIL() << "browser_check.mjs printed: " << out;
    }
    if (r.contains("skip") || r.contains("error") || !r.contains("samples")) break;
    const std::size_t seen = maps_drawn(r["samples"]);
    if (seen >= 2) break;
    if (attempt == 0) std::printf("browser, live slam: the page drew %zu map(s) during the run; following it once more\n", seen);
  }
  if (r.contains("skip")) GTEST_SKIP() << r["skip"].get<std::string>();
  ASSERT_FALSE(r.contains("error")) << r.dump(1);
  EXPECT_TRUE(r["console_errors"].empty()) << r["console_errors"].dump(1);
  EXPECT_EQ(r["hmap_exit"], 0) << r["hmap_output"].get<std::string>();  // SIGTERM ends it cleanly
  EXPECT_NE(r["hmap_output"].get<std::string>().find("still serving"), std::string::npos) << r["hmap_output"].get<std::string>();

  // The maps the page had drawn while the run went on (no reload or tile pending): the progress
  // line then names the scan of that map, and its path holds a pose per scan.
  const nlohmann::json& samples = r["samples"];
  ASSERT_FALSE(samples.empty());
  std::vector<nlohmann::json> drawn;
  int last_scan = 0;
  int last_drawn = 0;  // the boxes of the last map drawn
  for (const nlohmann::json& s : samples) {
    // A new map does not blink: the boxes of the one before stay on screen until its own are in.
    EXPECT_GE(s["on_screen"].get<int>(), s["busy"].get<bool>() ? last_drawn : s["boxes"].get<int>()) << s.dump();
    if (!s["busy"].get<bool>()) last_drawn = s["boxes"].get<int>();
    int scan = 0, of = 0;
    if (std::sscanf(s["progress"].get<std::string>().c_str(), "scan %d of %d", &scan, &of) == 2) {
      EXPECT_EQ(of, kLiveScans) << s.dump();
      EXPECT_GE(scan, last_scan) << "the progress went back: " << s.dump();  // it only advances
      last_scan = scan;
      if (!s["busy"].get<bool>()) {
        EXPECT_EQ(s["poses"].get<int>(), scan >= 2 ? scan : 0) << s.dump();
        EXPECT_LE(s["boxes"].get<int>(), s["hvoxels"].get<int>()) << s.dump();
        if (drawn.empty() || drawn.back()["version"] != s["version"]) drawn.push_back(s);
      }
    }
  }
  // At least two maps drawn before the end, the later with more poses and more boxes.
  ASSERT_GE(drawn.size(), 2U) << "the page saw too little of the run:\n" << samples.dump(1);
  EXPECT_GT(drawn.back()["poses"].get<int>(), drawn.front()["poses"].get<int>()) << samples.dump(1);
  EXPECT_GT(drawn.back()["boxes"].get<int>(), drawn.front()["boxes"].get<int>()) << samples.dump(1);

  // The end: the saved map, drawn, with the whole path.
  const nlohmann::json& last = samples.back();
  EXPECT_EQ(last["progress"].get<std::string>().rfind("done: " + std::to_string(kLiveScans) + " scans", 0), 0U) << last.dump();
  EXPECT_FALSE(last["busy"].get<bool>());
  EXPECT_EQ(last["poses"].get<int>(), kLiveScans);
  const std::size_t saved = load_hmap(dir / "slam" / "map.hmap").stats().hvoxels;
  EXPECT_EQ(last["hvoxels"].get<std::size_t>(), saved);
  EXPECT_GT(last["boxes"].get<int>(), drawn.front()["boxes"].get<int>());
  EXPECT_LE(last["boxes"].get<std::size_t>(), saved);
  std::printf("browser, live slam of %d scans: page ready %d ms after the URL, %zu samples, %zu maps drawn during the run "
              "(scans %s), last %d boxes of %zu HVoxels\n",
              kLiveScans, r["ready_ms"].get<int>(), samples.size(), drawn.size(),
              [&] {
                std::string s;
                for (const nlohmann::json& d : drawn) s += (s.empty() ? "" : ", ") + std::to_string(d["poses"].get<int>());
                return s;
              }().c_str(),
              last["boxes"].get<int>(), saved);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hmap::test
