// The CLI on broken input: exit code 2 and one line naming the file, the position and what was
// expected; never a stack trace, an abort or a sanitizer report.

#include <gtest/gtest.h>

#include <algorithm>

#include "common/test_data.hpp"
#include "reliability/reliability_util.hpp"

namespace hmap {
namespace {

namespace fs = std::filesystem;

class CliErrorsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::temp_dir("cli_errors");
    write("good.xyz", "1 2 0\n2 3 0\n3 4 0\n");
    write("good.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n");
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, std::string_view bytes) const {
    std::ofstream out(dir_ / name, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return (dir_ / name).string();
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  /// Runs hmap and checks the refusal: exit 2, one line "hmap: error: ...", holding every `parts`.
  void expect_refusal(const std::vector<std::string>& args, const std::vector<std::string>& parts) const {
    std::string out;
    const int code = test::run_hmap(args, dir_ / "log", out);
    std::string command;
    for (const auto& a : args) command += " " + a;
    EXPECT_EQ(code, 2) << "hmap" << command << "\n" << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << "hmap" << command << "\n" << out;
    EXPECT_TRUE(out.starts_with("hmap: error: ")) << out;
    for (const auto& part : parts) EXPECT_NE(out.find(part), std::string::npos) << "'" << part << "' not in: " << out;
  }

  fs::path dir_;
};

TEST_F(CliErrorsTest, BrokenScansNameTheFileAndThePosition) {
  const auto map = [&](const std::string& scan) {
    return std::vector<std::string>{"map", scan, "--poses", path("good.txt"), "--out", path("m.hmap")};
  };
  expect_refusal(map(write("huge.pcd",
                           "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1000000000000\n"
                           "HEIGHT 1\nPOINTS 1000000000000\nDATA binary\n" + std::string(24, '\0'))),
                 {"huge.pcd", "POINTS 1000000000000"});
  expect_refusal(map(write("huge.ply",
                           "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\n"
                           "property float y\nproperty float z\nend_header\n" + std::string(24, '\0'))),
                 {"huge.ply", "byte ", "1000000000"});
  expect_refusal(map(write("bad.xyz", "1 2 3\n4 x 6\n")), {"bad.xyz", "line 2"});
  expect_refusal(map(write("odd.bin", std::string(17, '\0'))), {"odd.bin", "16"});
  expect_refusal(map(write("huge.vtk", "# vtk DataFile Version 3.0\nt\nBINARY\nDATASET POLYDATA\n"
                                       "POINTS 4000000000 float\n" + std::string(12, '\0'))),
                 {"huge.vtk", "4000000000"});
  // A terminal escape in the file is written as \x1B, not sent to the user's terminal.
  expect_refusal(map(write("ctrl.xyz", "1 2 3\n4 \x1b[2J 6\n")), {"ctrl.xyz", "line 2", "\\x1B[2J"});
}

TEST_F(CliErrorsTest, BrokenPosesConfigsAndMapsNameTheFileAndThePosition) {
  const auto map_with = [&](std::vector<std::string> extra) {
    std::vector<std::string> args = {"map", path("good.xyz"), "--out", path("m.hmap")};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  };
  expect_refusal(map_with({"--poses", write("nan.txt", "1 0 0 nan 0 1 0 0 0 0 1 0\n")}), {"nan.txt", "line 1", "not finite"});
  expect_refusal(map_with({"--poses", write("scaled.txt", "# c\n2 0 0 0 0 2 0 0 0 0 2 0\n")}),
                 {"scaled.txt", "line 2", "not a rotation"});
  expect_refusal(map_with({"--poses", path("good.txt"), "--config", write("loop.yaml", "a: &x {b: *x}\n")}),
                 {"loop.yaml", "line 1"});
  expect_refusal(map_with({"--poses", path("good.txt"), "--config", write("syntax.yaml", "map: [1, \"\x01\n")}),
                 {"syntax.yaml", "line "});
  expect_refusal({"info", write("bad.hmap", std::string("\x89HMAP\r\n\x1a\x02\0\0\0\0\0\0\0", 16) + std::string(40, '\xff'))},
                 {"bad.hmap", "byte "});
}

TEST_F(CliErrorsTest, AbsurdParametersAreRefusedByName) {
  const std::vector<std::string> base = {"map", path("good.xyz"), "--poses", path("good.txt"), "--out", path("m.hmap")};
  auto with = [&](std::vector<std::string> extra) {
    auto args = base;
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  };
  expect_refusal(with({"--cell", "1e-6"}), {"map.cell_size"});
  expect_refusal(with({"--max-range", "1e9"}), {"map.max_range"});
  expect_refusal(with({"--set", "ground.iterations=4294967696"}), {"ground.iterations", "integer"});
  expect_refusal(with({"--set", "map.cell_size=nan"}), {"map.cell_size"});
}

}  // namespace
}  // namespace hmap
