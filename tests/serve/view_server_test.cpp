// The viewer's server (src/hmap/serve): what it serves, and everything it must refuse, asked by
// raw requests on a real socket.

#include "hmap/serve/view_server.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <thread>

#include "hmap/core/error.hpp"
#include "serve/http_get.hpp"

namespace hmap::serve {
namespace {

namespace fs = std::filesystem;
using test::http_get;
using test::http_request;

constexpr const char* kSecret = "SECRET-OUTSIDE-THE-ROOTS";

void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text;
}

std::shared_ptr<const view::MapScene> tiny_scene() {
  Params p;
  p.map.cell_size = 0.5;
  HMap map(p);
  auto c = map.column_for_update({1, 2});
  c.push_back({0.0F, 0.05F, 10.0F, 0.9F});
  c.push_back({1.5F, 2.0F, 4.0F, 0.7F});
  map.column_for_update({-3, 70}).push_back({0.5F, 1.0F, 3.0F, 0.6F});
  OccupancyGrid grid(0.5, 0.12, 0.97);
  grid.set({0, 0}, 0.0F);
  return std::make_shared<const view::MapScene>(std::move(map), std::vector<GroundPatch>{}, std::move(grid),
                                                std::vector<Eigen::Vector3d>{});
}

/// A server on a free port over a page and a three.js folder of its own, with a secret beside
/// them that no request may reach.
class ServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("hmap_serve_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    write(dir_ / "web/index.html", "<title>hmap view</title>");
    write(dir_ / "web/viewer.js", "// page");
    write(dir_ / "web/viewer.css", "body {}");
    write(dir_ / "web/other.html", kSecret);  // in the page's folder but not one of its files
    write(dir_ / "three/three.module.js", "export const REVISION = '111';");
    fs::create_directories(dir_ / "three/build");
    fs::create_symlink("../three.module.js", dir_ / "three/build/three.module.js");  // as Debian ships it
    write(dir_ / "three/examples/jsm/inside.js", "// inside");
    write(dir_ / "secret.js", kSecret);
    write(dir_ / "three/notjs.txt", kSecret);
    fs::create_symlink("../secret.js", dir_ / "three/escape.js");  // a link out of the root
    options_ = {"127.0.0.1", 0, dir_ / "web", dir_ / "three"};
    server_ = std::make_unique<ViewServer>(scene_, options_);
    server_->bind();
    thread_ = std::thread([this] { server_->run(); });
    // Wait until it answers.
    for (int k = 0; k < 200 && http_get(server_->port(), "/").status == 0; ++k) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  void TearDown() override {
    server_->stop();
    thread_.join();
    server_.reset();
    fs::remove_all(dir_);
  }
  int port() const { return server_->port(); }

  fs::path dir_;
  ServerOptions options_;
  std::shared_ptr<const view::MapScene> scene_ = tiny_scene();
  std::unique_ptr<ViewServer> server_;
  std::thread thread_;
};

TEST_F(ServerTest, ServesThePageAndThreeJs) {
  EXPECT_GT(port(), 0);
  EXPECT_EQ(server_->url(), "http://127.0.0.1:" + std::to_string(port()) + "/");
  EXPECT_EQ(http_get(port(), "/").body, "<title>hmap view</title>");
  EXPECT_EQ(http_get(port(), "/index.html").status, 200);
  EXPECT_EQ(http_get(port(), "/viewer.js").body, "// page");
  EXPECT_EQ(http_get(port(), "/viewer.css").status, 200);
  // Through Debian's link build/three.module.js -> ../three.module.js, which stays inside.
  EXPECT_EQ(http_get(port(), "/three/build/three.module.js").body, "export const REVISION = '111';");
  EXPECT_EQ(http_get(port(), "/three/examples/jsm/inside.js").body, "// inside");
}

TEST_F(ServerTest, RefusesEveryPathOutOfItsFiles) {
  const std::vector<std::string> attacks = {
      "/../secret.js",
      "/three/../secret.js",
      "/three/../../secret.js",
      "/three/%2e%2e/secret.js",
      "/three/%2E%2E/secret.js",
      "/three/..%2fsecret.js",
      "/three/..%2Fsecret.js",
      "/three/%2e%2e%2fsecret.js",
      "/three/%252e%252e/secret.js",
      "/three/.%2e/secret.js",
      "/three/build/../../secret.js",
      "/three/build/%2e%2e/%2e%2e/secret.js",
      "/three//secret.js",
      "/three/./three.module.js",
      "/three/..\\secret.js",
      "/three/%5c..%5csecret.js",
      "/three/escape.js",  // a symbolic link out of the root
      "/three/notjs.txt",
      "/three/three.module.js%00.txt",
      "/other.html",
      "/web/index.html",
      "/./index.html",
      "//index.html",
      "/index.html/",
      "/%2e%2e/secret.js",
      "/api/../secret.js",
      "/three/" + std::string(300, 'a') + "/../../secret.js",
      "../secret.js",
      "/etc/passwd",
      "/three/../../../../../../../../etc/passwd",
      "/three/%2e%2e/%2e%2e/%2e%2e/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
  };
  for (const std::string& target : attacks) {
    const test::HttpReply r = http_get(port(), target);
    EXPECT_TRUE(r.status == 404 || r.status == 400) << target << " -> " << r.status;
    EXPECT_EQ(r.body.find(kSecret), std::string::npos) << target;
    EXPECT_EQ(r.body.find("root:"), std::string::npos) << target;
  }
  // The control: the same secret inside the three.js root is served, so the refusals above are
  // the server's doing and not a broken request.
  write(dir_ / "three/secret.js", kSecret);
  EXPECT_EQ(http_get(port(), "/three/secret.js").body, kSecret);
}

TEST_F(ServerTest, RefusesUnknownRequestsAndMethods) {
  EXPECT_EQ(http_get(port(), "/api/nothing").status, 404);
  EXPECT_EQ(http_get(port(), "/favicon.ico").status, 404);
  EXPECT_EQ(http_get(port(), "/api/tile?a=0&b=0").status, 400);
  EXPECT_EQ(http_get(port(), "/api/tile?a=zero&b=0&level=0").status, 400);
  EXPECT_EQ(http_get(port(), "/api/tile?a=0&b=0&level=4").status, 400);
  EXPECT_EQ(http_get(port(), "/api/tile?a=0&b=0&level=-1").status, 400);
  EXPECT_EQ(http_get(port(), "/api/tile?a=99999999999&b=0&level=0").status, 400);
  EXPECT_EQ(http_get(port(), "/api/column?x=1").status, 400);
  EXPECT_EQ(http_get(port(), "/api/column?x=nan&y=0").status, 400);
  EXPECT_EQ(http_get(port(), "/api/column?x=1e300&y=0").status, 400);
  EXPECT_EQ(http_get(port(), "/api/column?x=9e8&y=0").status, 400);  // 1.8e9 cells out: beyond the map's keys
  EXPECT_EQ(http_request(port(), "POST", "/api/map").status, 405);
  EXPECT_EQ(http_request(port(), "DELETE", "/index.html").status, 405);
  EXPECT_EQ(http_request(port(), "PUT", "/three/secret.js").status, 405);
  EXPECT_FALSE(fs::exists(dir_ / "three/secret.js"));
}

TEST_F(ServerTest, MapDataIsWhatTheSceneEncodes) {
  const nlohmann::json info = nlohmann::json::parse(http_get(port(), "/api/map").body);
  EXPECT_EQ(info["hvoxels"], 3);
  EXPECT_EQ(info["tiles"], nlohmann::json::parse("[[-1, 1, 1], [0, 0, 2]]"));
  const test::HttpReply tile = http_get(port(), "/api/tile?a=0&b=0&level=0");
  ASSERT_EQ(tile.status, 200);
  const std::vector<std::uint8_t> bytes(tile.body.begin(), tile.body.end());
  EXPECT_EQ(view::decode_boxes(bytes), scene_->tile_boxes({0, 0}, 0));
  EXPECT_EQ(view::decode_boxes(bytes).size(), 2U);
  EXPECT_TRUE(http_get(port(), "/api/tile?a=5&b=5&level=0").body.empty());
  EXPECT_EQ(http_get(port(), "/api/grid").body, std::string(1, '\x32'));  // p = 0.5: 50
  const test::HttpReply column = http_get(port(), "/api/column?x=0.6&y=1.4");
  EXPECT_EQ(column.body, view::column_json(scene_->column(0.6, 1.4)));
  EXPECT_EQ(nlohmann::json::parse(column.body)["hvoxels"].size(), 2U);
}

// Scripts go as they are even to a browser that takes Brotli: cpp-httplib compresses text/* at
// Brotli's slowest quality, 3.8 s for three.js.
TEST_F(ServerTest, ScriptsAreSentUncompressed) {
  const test::HttpReply js = http_request(port(), "GET", "/three/build/three.module.js", 5, "Accept-Encoding: gzip, deflate, br\r\n");
  ASSERT_EQ(js.status, 200);
  EXPECT_EQ(js.body, "export const REVISION = '111';");
  EXPECT_EQ(js.headers.find("Content-Encoding"), std::string::npos) << js.headers;
  EXPECT_NE(js.headers.find("Content-Type: application/javascript"), std::string::npos) << js.headers;
}

// A live view replaces the map: /api/map says which one it is, with its progress, in one answer.
TEST_F(ServerTest, TheMapComesWithItsVersionAndProgress) {
  nlohmann::json info = nlohmann::json::parse(http_get(port(), "/api/map").body);
  EXPECT_EQ(info["version"], 1);
  EXPECT_EQ(info["progress"], "");
  EXPECT_EQ(info["hvoxels"], 3);
  Params p;
  HMap bigger(p);
  for (int i = 0; i < 5; ++i) bigger.column_for_update({i, 0}).push_back({0.0F, 0.1F, 5.0F, 0.9F});
  server_->set_scene(std::make_shared<const view::MapScene>(std::move(bigger), std::vector<GroundPatch>{}, std::nullopt,
                                                            std::vector<Eigen::Vector3d>{}),
                     "scan 2 of 5");
  info = nlohmann::json::parse(http_get(port(), "/api/map").body);
  EXPECT_EQ(info["version"], 2);
  EXPECT_EQ(info["progress"], "scan 2 of 5");
  EXPECT_EQ(info["hvoxels"], 5);
  EXPECT_EQ(nlohmann::json::parse(http_get(port(), "/api/status").body), nlohmann::json({{"version", 2}, {"progress", "scan 2 of 5"}}));
}

TEST_F(ServerTest, APortInUseIsNamed) {
  ViewServer second(scene_, {"127.0.0.1", port(), dir_ / "web", dir_ / "three"});
  try {
    second.bind();
    FAIL() << "bound a port in use";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("in use"), std::string::npos) << e.what();
  }
}

TEST(ServerSetup, MissingFilesAreNamed) {
  const fs::path nowhere = fs::temp_directory_path() / "hmap_no_such_dir";
  EXPECT_THROW(ViewServer(tiny_scene(), {"127.0.0.1", 0, nowhere, nowhere}), Error);
  ViewServer bad(tiny_scene(), {"not-an-address", 0, HMAP_WEB_DIR, HMAP_THREE_DIR});
  EXPECT_THROW(bad.bind(), Error);
}

TEST(StaticFile, OnlyThePageAndThreeJs) {
  const ServerOptions o{"127.0.0.1", 0, "/w", "/nonexistent-three"};
  EXPECT_EQ(static_file("/", o), fs::path("/w/index.html"));
  EXPECT_EQ(static_file("/viewer.js", o), fs::path("/w/viewer.js"));
  EXPECT_FALSE(static_file("/viewer.jsx", o));
  EXPECT_FALSE(static_file("/three/a.js", o));  // the root does not exist: nothing under it
  EXPECT_FALSE(static_file("/three/../a.js", o));
  EXPECT_FALSE(static_file("", o));
}

}  // namespace
}  // namespace hmap::serve
