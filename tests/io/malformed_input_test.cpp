// Every reader, fed every prefix of a valid file and randomly damaged copies of it, either
// returns a cloud or throws InputError: no crash, no other exception, no huge allocation.

#include <gtest/gtest.h>

#include <functional>
#include <random>
#include <string>

#include "hmap/io/cloud_reader.hpp"
#include "hmap/io/poses.hpp"
#include "io/io_test_util.hpp"

namespace hmap {
namespace {

using test::put;

class MalformedInputTest : public test::IoTest {
 protected:
  /// Reads every prefix of `bytes` and `damaged` random corruptions of it as file `name`.
  void survives(const std::string& name, const std::string& bytes,
                const std::function<void(const std::filesystem::path&)>& read) {
    const auto try_read = [&](const std::string& content, const std::string& what) {
      const auto path = write(name, content);
      try {
        read(path);
      } catch (const InputError&) {
        // expected for most damaged inputs
      } catch (const std::exception& e) {
        ADD_FAILURE() << what << ": " << e.what();
      }
    };
    for (std::size_t length = 0; length < bytes.size(); ++length) {
      try_read(bytes.substr(0, length), "prefix of " + std::to_string(length) + " bytes");
    }
    std::mt19937 rng(12345);  // fixed seed: the same damage every run
    std::uniform_int_distribution<std::size_t> position(0, bytes.size() - 1);
    std::uniform_int_distribution<int> byte(0, 255);
    for (int trial = 0; trial < 300; ++trial) {
      std::string damaged = bytes;
      for (int k = 0; k < 1 + trial % 4; ++k) damaged[position(rng)] = static_cast<char>(byte(rng));
      try_read(damaged, "damage trial " + std::to_string(trial));
    }
  }

  static void read_cloud_at(const std::filesystem::path& path) { (void)read_cloud(path); }
};

std::string binary_records(int points, int floats_per_point) {
  std::string data;
  for (int i = 0; i < points * floats_per_point; ++i) put<float>(data, 0.25F * static_cast<float>(i));
  return data;
}

TEST_F(MalformedInputTest, PcdAscii) {
  survives("a.pcd",
           "VERSION 0.7\nFIELDS x y z n\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 2\nWIDTH 3\nHEIGHT 1\n"
           "POINTS 3\nDATA ascii\n1 2 3 4 5\n6 7 8 9 10\nnan 1 2 3 4\n",
           read_cloud_at);
}

TEST_F(MalformedInputTest, PcdBinary) {
  survives("b.pcd",
           "VERSION 0.7\nFIELDS x y z i\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 4\nHEIGHT 1\n"
           "POINTS 4\nDATA binary\n" +
               binary_records(4, 4),
           read_cloud_at);
}

TEST_F(MalformedInputTest, PcdBinaryCompressed) {
  const std::string soa = binary_records(4, 4);
  std::string file =
      "VERSION 0.7\nFIELDS x y z i\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 2\nHEIGHT 2\n"
      "POINTS 4\nDATA binary_compressed\n";
  const std::string lzf = test::lzf_literals(soa);
  put<std::uint32_t>(file, static_cast<std::uint32_t>(lzf.size()));
  put<std::uint32_t>(file, static_cast<std::uint32_t>(soa.size()));
  survives("c.pcd", file + lzf, read_cloud_at);
}

TEST_F(MalformedInputTest, PlyBinaryWithLists) {
  std::string file =
      "ply\nformat binary_little_endian 1.0\nelement face 2\nproperty list uchar int v\n"
      "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "property list ushort uchar tags\nend_header\n";
  for (int f = 0; f < 2; ++f) {
    put<std::uint8_t>(file, 3);
    for (int i = 0; i < 3; ++i) put<std::int32_t>(file, i);
  }
  for (int v = 0; v < 3; ++v) {
    file += binary_records(1, 3);
    put<std::uint16_t>(file, 2);
    file += "ab";
  }
  survives("b.ply", file, read_cloud_at);
}

TEST_F(MalformedInputTest, PlyAscii) {
  survives("a.ply",
           "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int v\nelement vertex 2\n"
           "property float x\nproperty float y\nproperty double z\nend_header\n3 0 1 2\n1 2 3\n4 5 6\n",
           read_cloud_at);
}

TEST_F(MalformedInputTest, XyzAndKitti) {
  survives("p.csv", "x,y,z,i\n1,2,3,4\n5 ,6 ,7,8\n", read_cloud_at);
  survives("s.bin", binary_records(3, 4), read_cloud_at);
}

TEST_F(MalformedInputTest, Poses) {
  survives("poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n0 -1 0 1 1 0 0 2 0 0 1 3\n",
           [](const std::filesystem::path& path) { (void)read_poses(path); });
  survives("traj.txt", "# t x y z qx qy qz qw\n0.5 1 2 3 0 0 0 1\n",
           [](const std::filesystem::path& path) { (void)read_poses(path); });
}

}  // namespace
}  // namespace hmap
