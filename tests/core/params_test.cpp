#include "hmap/core/params.hpp"

#include <gtest/gtest.h>

#include <cmath>
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

}  // namespace
}  // namespace hmap
