#include "hmap/core/format.hpp"

#include <gtest/gtest.h>

#include <string>

#include "hmap/core/checked.hpp"

namespace hmap {
namespace {

TEST(Format, PrintsWhatSnprintfWouldShortOrLong) {
  EXPECT_EQ(format("%d,%.2f", 3, 0.5), "3,0.50");
  // 1e30 with four decimals: 31 digits, a point and 4 decimals; the CSV writers' 96-byte buffer
  // held three of them only by luck and a pose of 1e30 overflowed it.
  const std::string big = format("%.4f,%.4f,%.4f\n", 1e30, -1e30, 1e30);
  EXPECT_EQ(big, "1000000000000000019884624838656.0000,-1000000000000000019884624838656.0000,"
                 "1000000000000000019884624838656.0000\n");
  // Longer than the internal first buffer (256 bytes).
  const std::string long_line = format("%.1f", 1e300);
  EXPECT_EQ(long_line.size(), 301U + 2U);
  EXPECT_EQ(long_line.substr(long_line.size() - 2), ".0");
  EXPECT_EQ(format("%s", std::string(1000, 'x').c_str()), std::string(1000, 'x'));
}

TEST(Checked, FloorAndCeilRefuseWhatTheTypeCannotHold) {
  EXPECT_EQ(floor_to<int>(-0.5), -1);
  EXPECT_EQ(ceil_to<int>(2.0000001), 3);
  EXPECT_EQ(floor_to<int>(2147483647.9), 2147483647);
  EXPECT_FALSE(floor_to<int>(2147483648.0));
  EXPECT_EQ(floor_to<int>(-2147483648.0), -2147483648LL);
  EXPECT_FALSE(floor_to<int>(-2147483648.5));
  EXPECT_FALSE(floor_to<int>(1e12));
  EXPECT_FALSE(floor_to<int>(std::nan("")));
  EXPECT_FALSE(floor_to<long long>(1e300));
  EXPECT_FALSE(ceil_to<int>(-std::numeric_limits<double>::infinity()));
}

TEST(Checked, CountsBeyondTheLimitAreRefusedWithWhatTheyCount) {
  EXPECT_EQ(checked_count<int>(4.2, 10, "x"), 5);
  EXPECT_EQ(checked_count<int>(0.0, 10, "x"), 0);
  try {
    (void)checked_count<int>(1e12, 64, "the coarse search in yaw");
    FAIL();
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "the coarse search in yaw needs 1e+12 steps, at most 64");
  }
  EXPECT_THROW((void)checked_count<int>(std::nan(""), 64, "x"), Error);
  EXPECT_THROW((void)checked_count<int>(-1.5, 64, "x"), Error);
}

}  // namespace
}  // namespace hmap
