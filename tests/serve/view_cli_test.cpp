// `hmap view` as a user runs it: the URL printed and served, and bad input as one line, exit 2.

#include <gtest/gtest.h>

#include <netinet/in.h>
#include <sys/socket.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "serve/http_get.hpp"
#include "serve/test_map.hpp"
#include "serve/view_process.hpp"

namespace hmap::test {
namespace {

namespace fs = std::filesystem;

struct CliRun {
  int code = -1;
  std::string out;
};

CliRun run_hmap(const std::string& args) {
  CliRun r;
  FILE* pipe = ::popen((hmap_bin() + " " + args + " 2>&1").c_str(), "r");
  std::array<char, 4096> buf{};
  for (std::size_t n; (n = std::fread(buf.data(), 1, buf.size(), pipe)) > 0;) r.out.append(buf.data(), n);
  const int status = ::pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

CliRun run_view(const std::string& args) { return run_hmap("view " + args); }

std::size_t lines(const std::string& s) { return static_cast<std::size_t>(std::count(s.begin(), s.end(), '\n')); }

class ViewCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("hmap_view_cli_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    save_room(dir_ / "room.hmap");
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(ViewCli, PrintsTheUrlAndServesTheMap) {
  ViewProcess view({(dir_ / "room.hmap").string(), "--port", "0"});
  ASSERT_FALSE(view.url().empty()) << view.output();
  EXPECT_EQ(view.url().rfind("http://127.0.0.1:", 0), 0U) << view.url();  // loopback unless told
  const int port = std::stoi(view.url().substr(view.url().rfind(':') + 1));
  EXPECT_NE(http_get(port, "/").body.find("<title>hmap view</title>"), std::string::npos);
  EXPECT_NE(http_get(port, "/three/build/three.module.js").body.find("REVISION"), std::string::npos);
  EXPECT_NE(http_get(port, "/three/examples/jsm/controls/OrbitControls.js").body.find("OrbitControls"), std::string::npos);
  EXPECT_NE(http_get(port, "/api/map").body.find("\"hvoxels\":" + std::to_string(24 * 16 + 24)), std::string::npos);
  EXPECT_EQ(http_get(port, "/three/%2e%2e/%2e%2e/%2e%2e/etc/passwd").status, 404);
  EXPECT_EQ(view.stop(), 0) << view.output();  // SIGTERM stops it cleanly
}

TEST_F(ViewCli, ReadsATrajectory) {
  std::ofstream(dir_ / "poses.txt") << "1 0 0 0.5 0 1 0 0.5 0 0 1 1\n1 0 0 2.5 0 1 0 1.5 0 0 1 1\n";
  ViewProcess view({(dir_ / "room.hmap").string(), "--port", "0", "--trajectory", (dir_ / "poses.txt").string()});
  ASSERT_FALSE(view.url().empty()) << view.output();
  const int port = std::stoi(view.url().substr(view.url().rfind(':') + 1));
  EXPECT_NE(http_get(port, "/api/map").body.find("\"trajectory\":[[0.5,0.5,1.0],[2.5,1.5,1.0]]"), std::string::npos);
}

// A PVOX map of `hmap pvox`: its occupied voxels, as many as `hmap info` counts, coloured by probability.
TEST_F(ViewCli, ShowsAPvoxMap) {
  {
    std::ofstream xyz(dir_ / "cloud.xyz");
    for (int i = 0; i < 40; ++i) {
      for (int j = 0; j < 30; ++j) xyz << 2.0 + 0.05 * i << " " << -0.75 + 0.05 * j << " " << (i % 10 == 0 ? 0.05 * j : 0.0) << "\n";
    }
  }
  const CliRun pvox = run_hmap("pvox " + (dir_ / "cloud.xyz").string() + " --out " + (dir_ / "pv").string());
  ASSERT_EQ(pvox.code, 0) << pvox.out;
  const CliRun info = run_hmap("info " + (dir_ / "pv/map.pvox").string() + " --json");
  ASSERT_EQ(info.code, 0) << info.out;
  const std::string occupied = info.out.substr(info.out.find("\"occupied_voxels\":") + 18);
  ViewProcess view({(dir_ / "pv/map.pvox").string(), "--port", "0"});
  ASSERT_FALSE(view.url().empty()) << view.output();
  const int port = std::stoi(view.url().substr(view.url().rfind(':') + 1));
  const std::string map = http_get(port, "/api/map").body;
  EXPECT_NE(map.find("\"format\":\"pvox\""), std::string::npos) << map;
  EXPECT_NE(map.find("\"hvoxels\":" + occupied.substr(0, occupied.find_first_of(",}"))), std::string::npos) << map << "\n" << info.out;
}

// hmap map --view: the page follows the map as scans come in, then serves the saved map.
TEST_F(ViewCli, MapServesTheMapWhileItGrows) {
  const CliRun sim = run_hmap("simulate --scene boxes --sensor vlp16 --frames 4 --out " + (dir_ / "sim").string());
  ASSERT_EQ(sim.code, 0) << sim.out;
  ViewProcess map({"--kitti", (dir_ / "sim").string(), "--out", (dir_ / "m.hmap").string(), "--view", "--view-port", "0"}, "map");
  ASSERT_FALSE(map.url().empty()) << map.output();
  const int port = std::stoi(map.url().substr(map.url().rfind(':') + 1));
  std::string status;
  for (int k = 0; k < 600 && status.find("\"progress\":\"done: 4 scans") == std::string::npos; ++k) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    status = http_get(port, "/api/status").body;
  }
  ASSERT_NE(status.find("done: 4 scans"), std::string::npos) << status << map.output();
  // What is served is the saved map, with the path of its scans.
  const nlohmann::json info = nlohmann::json::parse(http_get(port, "/api/map").body);
  EXPECT_EQ(info["hvoxels"].get<std::size_t>(), load_hmap(dir_ / "m.hmap").stats().hvoxels);
  EXPECT_GT(info["hvoxels"].get<std::size_t>(), 0U);
  EXPECT_EQ(info["trajectory"].size(), 4U);
  // The event stream says so too (read for a second: it stays open).
  const HttpReply events = http_request(port, "GET", "/api/events", 1);
  EXPECT_EQ(events.status, 200);
  EXPECT_NE(events.body.find("data: {\"progress\":\"done: 4 scans"), std::string::npos) << events.body;
  EXPECT_EQ(map.stop(), 0) << map.output();
  EXPECT_NE(map.output().find("still serving"), std::string::npos) << map.output();
}

// hmap slam --view: the same, with the estimated path.
TEST_F(ViewCli, SlamServesTheMapWhileItGrows) {
  const CliRun sim = run_hmap("simulate --scene boxes --sensor vlp16 --frames 3 --out " + (dir_ / "sim").string());
  ASSERT_EQ(sim.code, 0) << sim.out;
  ViewProcess slam({"--kitti", (dir_ / "sim").string(), "--out", (dir_ / "slam").string(), "--view", "--view-port", "0"}, "slam");
  ASSERT_FALSE(slam.url().empty()) << slam.output();
  const int port = std::stoi(slam.url().substr(slam.url().rfind(':') + 1));
  std::string status;
  for (int k = 0; k < 600 && status.find("\"progress\":\"done: 3 scans") == std::string::npos; ++k) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    status = http_get(port, "/api/status").body;
  }
  ASSERT_NE(status.find("done: 3 scans"), std::string::npos) << status << slam.output();
  const nlohmann::json info = nlohmann::json::parse(http_get(port, "/api/map").body);
  EXPECT_EQ(info["hvoxels"].get<std::size_t>(), load_hmap(dir_ / "slam/map.hmap").stats().hvoxels);
  EXPECT_EQ(info["trajectory"].size(), 3U);
  EXPECT_EQ(slam.stop(), 0) << slam.output();
}

TEST_F(ViewCli, BadInputIsOneLineAndExitTwo) {
  const CliRun missing = run_view((dir_ / "nothing.hmap").string() + " --port 0");
  EXPECT_EQ(missing.code, 2) << missing.out;
  EXPECT_EQ(lines(missing.out), 1U) << missing.out;
  std::ofstream(dir_ / "bad.hmap") << "not a map";
  const CliRun bad = run_view((dir_ / "bad.hmap").string() + " --port 0");
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_EQ(lines(bad.out), 1U) << bad.out;
  for (const char* port : {"99999", "-1", "http"}) {
    const CliRun r = run_view((dir_ / "room.hmap").string() + " --port " + port);
    EXPECT_EQ(r.code, 2) << port << ": " << r.out;
    EXPECT_EQ(lines(r.out), 1U) << r.out;
  }
  const CliRun address = run_view((dir_ / "room.hmap").string() + " --port 0 --bind 300.1.2.3");
  EXPECT_EQ(address.code, 2) << address.out;
  EXPECT_EQ(lines(address.out), 1U) << address.out;
}

TEST_F(ViewCli, APortInUseIsOneLineAndExitTwo) {
  // Hold a port: bind and listen on one the system picks.
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(fd, 1), 0);
  socklen_t len = sizeof addr;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  const CliRun r = run_view((dir_ / "room.hmap").string() + " --port " + std::to_string(ntohs(addr.sin_port)));
  ::close(fd);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(lines(r.out), 1U) << r.out;
  EXPECT_NE(r.out.find("in use"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace hmap::test
