#include "hmap/io/pgm_export.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "common/test_data.hpp"
#include "hmap/core/error.hpp"

namespace hmap {
namespace {

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

TEST(PgmExportTest, WritesWhatMapServerReads) {
  const auto dir = test::temp_dir("pgm");
  OccupancyGrid g(0.05, 0.12, 0.97);
  g.update({-2, 10}, log_odds(0.9));  // occupied, the north-west corner
  g.update({1, 8}, log_odds(0.1));    // free, the south-east corner
  g.update({0, 9}, 0.0F);             // observed, 0.5: unknown
  write_pgm_map(dir / "map.pgm", g);
  const std::string pgm = slurp(dir / "map.pgm");
  std::istringstream in(pgm);
  std::string magic, comment;
  int w = 0, h = 0, maxval = 0;
  in >> magic;
  in.ignore();
  std::getline(in, comment);
  in >> w >> h >> maxval;
  in.ignore();
  EXPECT_EQ(magic, "P5");
  EXPECT_EQ(w, 4);  // i from -2 to 1
  EXPECT_EQ(h, 3);  // j from 8 to 10
  EXPECT_EQ(maxval, 255);
  const std::string px = pgm.substr(static_cast<std::size_t>(in.tellg()));
  ASSERT_EQ(px.size(), 12U);
  EXPECT_EQ(static_cast<unsigned char>(px[0 * 4 + 0]), 0);    // (-2, 10): row 0, column 0
  EXPECT_EQ(static_cast<unsigned char>(px[2 * 4 + 3]), 254);  // (1, 8): last row, last column
  EXPECT_EQ(static_cast<unsigned char>(px[1 * 4 + 2]), 205);  // (0, 9): unknown
  EXPECT_EQ(static_cast<unsigned char>(px[0 * 4 + 3]), 205);  // never observed
  const std::string yaml = slurp(dir / "map.yaml");
  EXPECT_NE(yaml.find("image: map.pgm\n"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("resolution: 0.05"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("origin: [-0.1, 0.4"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("negate: 0\n"), std::string::npos);
  EXPECT_NE(yaml.find("occupied_thresh: 0.65"), std::string::npos);
  EXPECT_NE(yaml.find("free_thresh: 0.196"), std::string::npos);
  EXPECT_NE(yaml.find("mode: trinary"), std::string::npos);
  std::filesystem::remove_all(dir);
}

// Origins are index · cell in exact decimal: the double product -219 · 0.1 prints as
// -21.900000000000002, which no person writes and which reads back as a different number.
TEST(PgmExportTest, OriginsAreTheShortestExactDecimal) {
  EXPECT_EQ(decimal_multiple(-219, 0.1), "-21.9");
  EXPECT_EQ(decimal_multiple(3, 0.1), "0.3");
  EXPECT_EQ(decimal_multiple(0, 0.1), "0");
  EXPECT_EQ(decimal_multiple(-4, 0.25), "-1");
  EXPECT_EQ(decimal_multiple(7, 1e-5), "0.00007");
  EXPECT_EQ(decimal_multiple(-12, 0.05), "-0.6");
  EXPECT_EQ(decimal_multiple(5, 2.0), "10");
  EXPECT_EQ(decimal_multiple(100000, 0.3), "30000");
  EXPECT_EQ(decimal_multiple(-2147483647, 0.123456789), "-265121435.488629483");
  // Brute-force twin: for every index the decimal reads back to the nearest double of the exact product.
  for (int i = -3000; i <= 3000; i += 7) {
    const std::string d = decimal_multiple(i, 0.1);
    EXPECT_NEAR(std::stod(d), i * 0.1, 1e-9) << i;
    EXPECT_LE(d.size(), std::to_string(i).size() + 2) << d;
  }
  const auto dir = test::temp_dir("pgm_origin");
  OccupancyGrid g(0.1, 0.12, 0.97);
  g.update({-219, -3}, log_odds(0.9));
  g.update({-200, 4}, log_odds(0.1));
  write_pgm_map(dir / "o", g);
  const std::string yaml = slurp(dir / "o.yaml");
  EXPECT_NE(yaml.find("origin: [-21.9, -0.3, 0.0]"), std::string::npos) << yaml;
  std::filesystem::remove_all(dir);
}

// One clear ground pass (p = K_g = 0.3, stored as float log-odds) is free when the map's own reading
// is used, undecided with map_server's 0.196; the YAML stays map_server's either way.
TEST(PgmExportTest, OnePassIsFreeByTheMapsReading) {
  const auto dir = test::temp_dir("pgm_reading");
  OccupancyGrid g(0.05, 0.12, 0.97);
  g.update({0, 0}, log_odds(0.3));  // one pass over the ground
  g.update({1, 0}, log_odds(0.4));  // a ground cell's own ray at delta = 0: undecided either way
  PgmExportParams params;
  params.reading = GridReading::for_map(outdoor_preset().occupancy);
  for (const bool own : {false, true}) {
    write_pgm_map(dir / "m", g, own ? params : PgmExportParams{});
    const std::string pgm = slurp(dir / "m.pgm");
    ASSERT_GE(pgm.size(), 2U);
    const std::string px = pgm.substr(pgm.size() - 2);  // one row of two cells
    EXPECT_EQ(static_cast<unsigned char>(px[0]), own ? 254 : 205);
    EXPECT_EQ(static_cast<unsigned char>(px[1]), 205);
    EXPECT_NE(slurp(dir / "m.yaml").find("free_thresh: 0.196"), std::string::npos);
  }
  std::filesystem::remove_all(dir);
}

TEST(PgmExportTest, EmptyGridIsAnError) {
  const auto dir = test::temp_dir("pgm_empty");
  OccupancyGrid g(0.05, 0.12, 0.97);
  EXPECT_THROW(write_pgm_map(dir / "m", g), Error);
  EXPECT_FALSE(std::filesystem::exists(dir / "m.pgm"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace hmap
