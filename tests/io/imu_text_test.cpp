#include "hmap/io/imu_text.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "hmap/core/error.hpp"
#include "io/io_test_util.hpp"

namespace hmap {
namespace {

using test::contains;
using test::input_error_of;

class ImuTextTest : public test::IoTest {};

TEST_F(ImuTextTest, ReadsSpacesCommasCommentsAndOrientation) {
  const auto path = write("imu.txt",
                          "# t gx gy gz ax ay az [qx qy qz qw]\n"
                          "\n"
                          "0.00 0.1 -0.2 0.3 0.0 0.0 9.81\n"
                          "0.005,0.1,-0.2,0.3,0.01,-0.02,9.8\r\n"
                          "0.010\t0 0 0\t0 0 9.81  0 0 0 2\n");
  const ImuSamples s = read_imu_text(path);
  ASSERT_EQ(s.size(), 3U);
  EXPECT_DOUBLE_EQ(s[0].t, 0.0);
  EXPECT_EQ(s[0].gyro, Eigen::Vector3d(0.1, -0.2, 0.3));
  EXPECT_EQ(s[1].accel, Eigen::Vector3d(0.01, -0.02, 9.8));
  EXPECT_FALSE(s[1].orientation.has_value());
  ASSERT_TRUE(s[2].orientation.has_value());
  EXPECT_DOUBLE_EQ(s[2].orientation->w(), 1.0);  // normalised
}

TEST_F(ImuTextTest, NanosecondStampsAsEurocWritesThem) {
  const ImuSamples s = read_imu_text(write("data.csv",
                                           "#timestamp [ns],w_RS_S_x,w_RS_S_y,w_RS_S_z,a_RS_S_x,a_RS_S_y,a_RS_S_z\n"
                                           "1403636579758555392,-0.099,0.14,0.02,8.1,-0.13,-3.6\n"
                                           "1403636579763555584,-0.099,0.13,0.02,8.1,-0.14,-3.6\n"));
  ASSERT_EQ(s.size(), 2U);
  EXPECT_NEAR(s[1].t - s[0].t, 0.005, 1e-6);
}

TEST_F(ImuTextTest, BadLinesAreRefusedWithFileAndLine) {
  const std::string good = "0 0 0 0 0 0 9.81\n";
  const auto err = [&](const std::string& name, const std::string& text) {
    return input_error_of([&] { (void)read_imu_text(write(name, text)); });
  };
  std::string e = err("few.txt", good + "0.1 0 0 0 0 9.81\n");
  EXPECT_TRUE(contains(e, "few.txt: line 2"));
  EXPECT_TRUE(contains(e, "found 6"));
  e = err("nan.txt", good + "0.1 0 nan 0 0 0 9.81\n");
  EXPECT_TRUE(contains(e, "nan.txt: line 2"));
  EXPECT_TRUE(contains(e, "not a finite number"));
  e = err("inf.txt", "# c\n" + good + "0.1 0 0 0 0 0 inf\n");
  EXPECT_TRUE(contains(e, "inf.txt: line 3"));
  e = err("word.txt", good + "0.1 0 0 0 0 0 g\n");
  EXPECT_TRUE(contains(e, "word.txt: line 2"));
  e = err("back.txt", "0.2 0 0 0 0 0 9.81\n0.3 0 0 0 0 0 9.81\n0.3 0 0 0 0 0 9.81\n");
  EXPECT_TRUE(contains(e, "back.txt: line 3"));
  EXPECT_TRUE(contains(e, "not after"));
  e = err("zero_q.txt", "0.2 0 0 0 0 0 9.81 0 0 0 0\n");
  EXPECT_TRUE(contains(e, "zero_q.txt: line 1"));
  e = err("empty.txt", "# nothing\n\n");
  EXPECT_TRUE(contains(e, "no IMU sample"));
  e = err("eight.txt", "0.2 0 0 0 0 0 9.81 1\n");
  EXPECT_TRUE(contains(e, "found 8"));
}

}  // namespace
}  // namespace hmap

namespace hmap {
namespace {

// What write_imu_text writes, read_imu_text reads back exactly (shortest round-trip decimals),
// the orientation where a sample has one; a non-finite value is refused and nothing is written.
TEST_F(ImuTextTest, WrittenSamplesReadBackExactly) {
  ImuSamples in(3);
  for (std::size_t k = 0; k < in.size(); ++k) {
    in[k].t = 0.005 * static_cast<double>(k) + 1.0 / 3.0;
    in[k].gyro = {0.1 * static_cast<double>(k), -1e-7, 3.0};
    in[k].accel = {0.01, -0.02, 9.80665 + 1e-12 * static_cast<double>(k)};
  }
  in[1].orientation = Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5);
  const auto path = dir_ / "w.txt";
  write_imu_text(path, in);
  const ImuSamples out = read_imu_text(path);
  ASSERT_EQ(out.size(), in.size());
  for (std::size_t k = 0; k < in.size(); ++k) {
    EXPECT_EQ(out[k].t, in[k].t);
    EXPECT_EQ(out[k].gyro, in[k].gyro);
    EXPECT_EQ(out[k].accel, in[k].accel);
    EXPECT_EQ(out[k].orientation.has_value(), in[k].orientation.has_value());
  }
  EXPECT_NEAR(out[1].orientation->angularDistance(*in[1].orientation), 0.0, 1e-12);
  in[2].accel.x() = std::nan("");
  EXPECT_THROW(write_imu_text(dir_ / "bad.txt", in), Error);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "bad.txt"));
}

}  // namespace
}  // namespace hmap
