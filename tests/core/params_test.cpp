#include "hmap/core/params.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "hmap/core/error.hpp"

namespace hmap {
namespace {

/// Sets parameter `name` through param_refs (as config files, --set and .hmap files do); returns
/// the error message, or "" when the value was taken.
std::string set(Params& params, const std::string& name, double value) {
  for (auto& r : param_refs(params)) {
    if (r.name != name) continue;
    try {
      r.set(value);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }
  ADD_FAILURE() << "no parameter " << name;
  return "";
}

TEST(ParamsTest, IntegerParametersRoundAndRefuseWhatTheirTypeCannotHold) {
  Params p;
  EXPECT_EQ(set(p, "ground.iterations", 12.4), "");
  EXPECT_EQ(p.ground.iterations, 12);
  EXPECT_EQ(set(p, "ground.seed", 18446744073709549568.0), "");  // 2^64 - 2048: the largest double below 2^64
  EXPECT_EQ(p.ground.seed, 18446744073709549568ULL);
  // A cast would wrap 2^32 + 400 to 400 and accept it silently.
  const std::string wrapped = set(p, "ground.iterations", 4294967696.0);
  EXPECT_NE(wrapped.find("ground.iterations"), std::string::npos) << wrapped;
  EXPECT_NE(wrapped.find("must be an integer in [-2147483648, 2147483647]"), std::string::npos) << wrapped;
  EXPECT_EQ(p.ground.iterations, 12);
  EXPECT_NE(set(p, "ground.seed", -1.0), "");
  EXPECT_NE(set(p, "ground.seed", 18446744073709551616.0), "");  // 2^64
  EXPECT_NE(set(p, "ground.iterations", std::nan("")), "");
  EXPECT_NE(set(p, "ground.iterations", 1e30), "");
  EXPECT_NE(set(p, "map.free_space", 256.0), "");  // would wrap to 0 in the uint8_t enum
  EXPECT_EQ(set(p, "map.free_space", 1.0), "");
  EXPECT_EQ(p.map.free_space, FreeSpaceMode::kNone);
}

TEST(ParamsTest, AbsurdValuesAreRefusedByName) {
  Params p;
  p.map.cell_size = 1e-6;
  EXPECT_THROW(validate(p), Error);
  try {
    validate(p);
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("map.cell_size"), std::string::npos) << e.what();
  }
  p = Params{};
  p.map.max_range = 1e9;
  try {
    validate(p);
    ADD_FAILURE() << "max_range 1e9 accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("map.max_range"), std::string::npos) << e.what();
  }
}

TEST(ErrorTest, MessagesAreOneLineOfPrintableText) {
  const InputError e("a\nb.pcd", "line 3", std::string("unknown type '\x1b[31m\r\n'"));
  EXPECT_STREQ(e.what(), "a\\x0Ab.pcd: line 3: unknown type '\\x1B[31m\\x0D\\x0A'");
  EXPECT_STREQ(Error("tab\there").what(), "tab\\x09here");
  EXPECT_STREQ(Error("Ünïcode ok, 30 m²").what(), "Ünïcode ok, 30 m²");
  // A token as long as a file is cut: the start of the message stays, with the count cut.
  const std::string long_message = Error("f.pcd: line 1: unknown keyword '" + std::string(5000, 'A') + "'").what();
  EXPECT_EQ(long_message.substr(0, 32), "f.pcd: line 1: unknown keyword '");
  EXPECT_EQ(long_message.substr(1024), " [4009 more bytes cut]");
  // Bytes that are not UTF-8 (random data quoted from a file), and C1 controls (U+009B is CSI).
  EXPECT_STREQ(Error(std::string("a\xff\xc3(\xc2\x9b[31m\xe2\x82")).what(), "a\\xFF\\xC3(\\xC2\\x9B[31m\\xE2\\x82");
}

/// validate() of `params` with `name` set to `value`: "" when accepted, else the message.
std::string validate_with(const std::string& name, double value) {
  Params p;
  const std::string refused = set(p, name, value);
  if (!refused.empty()) return refused;
  try {
    validate(p);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(ParamsTest, EveryParameterHasAFiniteRangeTheDefaultsLieIn) {
  for (const Params& preset : {indoor_preset(), room_preset(), outdoor_preset()}) {
    Params p = preset;
    for (const auto& r : param_refs(p)) {
      EXPECT_TRUE(std::isfinite(r.range.min) && std::isfinite(r.range.max)) << r.name;
      EXPECT_LT(r.range.min, r.range.max) << r.name;
      EXPECT_TRUE(r.range.contains(r.get())) << r.name << " = " << r.get() << " outside " << r.range.text();
    }
    EXPECT_NO_THROW(validate(preset));
  }
}

// Every parameter at the ends of its range, just beyond them, at NaN, ±infinity and ±1e300: a
// value beyond the range is refused with the parameter's name, its value and its range; any
// other outcome is acceptance or a refusal naming a parameter (a rule between two), never a crash.
TEST(ParamsTest, EveryParameterAtItsExtremesIsTakenOrRefusedByName) {
  Params scratch;
  const auto refs = param_refs(scratch);
  ASSERT_EQ(refs.size(), 80U);  // a new parameter needs its range, and a look at this test
  const double inf = std::numeric_limits<double>::infinity();
  for (const auto& r : refs) {
    const ParamRange& range = r.range;
    const double lo_in = range.min_open ? std::nextafter(range.min, inf) : range.min;
    const double hi_in = range.max_open ? std::nextafter(range.max, -inf) : range.max;
    const double lo_out = range.min_open ? range.min : std::nextafter(range.min, -inf);
    const double hi_out = range.max_open ? range.max : std::nextafter(range.max, inf);
    for (const double v : {lo_in, hi_in}) {
      const std::string m = validate_with(r.name, v);
      EXPECT_TRUE(m.empty() || m.starts_with("parameter ")) << r.name << " = " << v << ": " << m;
    }
    const bool integer = r.name == "ground.iterations" || r.name == "ground.seed" || r.name == "map.free_space" ||
                         r.name.starts_with("slam.interpolation") || r.name == "slam.max_iterations" ||
                         r.name == "slam.max_hvoxels" || r.name == "slam.attitude_iterations" || r.name == "slam.deskew" ||
                         r.name == "slam.loop_closure" || r.name == "slam.loop_submap_scans" ||
                         r.name == "slam.loop_candidates" || r.name == "slam.wall_refine" || r.name == "slam.wall_iterations" ||
                         r.name == "slam.hvoxel_centroids";
    for (const double v : {lo_out, hi_out, std::nan(""), inf, -inf, 1e300, -1e300}) {
      // An integer just beyond its range rounds back into it: step a whole unit out instead.
      double out = integer && std::isfinite(v) && std::abs(v) < 1e300 ? (v < range.min ? range.min - 1.0 : range.max + 1.0) : v;
      if (out == range.max) out = std::nextafter(out, inf);  // 2^64 - 2048 + 1 is 2^64 - 2048 again
      const std::string m = validate_with(r.name, out);
      ASSERT_FALSE(m.empty()) << r.name << " = " << out << " accepted";
      EXPECT_TRUE(m.starts_with("parameter " + r.name + " = ")) << m;
      // Not a type's limit first: then the message names the range.
      if (m.find("must be an integer") == std::string::npos) {
        EXPECT_NE(m.find("is out of its range " + range.text()), std::string::npos) << m;
      }
    }
  }
}

TEST(ParamsTest, RangesAreHandComputedAndNamedInTheMessage) {
  EXPECT_EQ(validate_with("ground.iterations", 2147483647.0),
            "parameter ground.iterations = 2147483647 is out of its range [0, 100000]");
  EXPECT_EQ(validate_with("occupancy.clamp_min", 0.5), "parameter occupancy.clamp_min = 0.5 is out of its range (0, 0.5)");
  EXPECT_EQ(validate_with("slam.coarse_translation", 300.0),
            "parameter slam.coarse_translation = 300 is out of its range [0, 20] m");
  EXPECT_EQ(validate_with("slam.coarse_rotation", 1e12), "parameter slam.coarse_rotation = 1000000000000 is out of its range "
                                                        "[0, 3.141592653589793] rad");
  EXPECT_EQ(validate_with("map.cell_size", std::nan("")), "parameter map.cell_size = nan is out of its range [0.001, 100] m");
  // The coarse search of 2-cell steps walks at most 50 each way: 20 m at 0.25 m cells is 40 steps,
  // at 0.05 m (indoor) 200.
  EXPECT_EQ(validate_with("slam.coarse_translation", 20.0), "");
  Params indoor = indoor_preset();
  indoor.slam.coarse_translation = 5.5;
  try {
    validate(indoor);
    ADD_FAILURE() << "5.5 m at 0.05 m cells accepted";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "parameter slam.coarse_translation = 5.5 is invalid: must be at most 100 cells (100 * map.cell_size)");
  }
  indoor.slam.coarse_translation = 5.0;
  EXPECT_NO_THROW(validate(indoor));
}

}  // namespace
}  // namespace hmap
