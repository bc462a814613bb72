// Header claims beyond the file are refused before anything is allocated from them (the PCD,
// PLY, VTK and .hmap claims are tested beside their readers; the PNG one here).
#include <gtest/gtest.h>

#include "hmap/io/depth_image.hpp"
#include "io/io_test_util.hpp"

namespace hmap {
namespace {

/// CRC-32 of PNG chunks (ISO 3309), bit by bit: small inputs only.
std::uint32_t crc32(std::string_view bytes) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (const char b : bytes) {
    c ^= static_cast<unsigned char>(b);
    for (int k = 0; k < 8; ++k) c = (c & 1u) != 0 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
  }
  return c ^ 0xFFFFFFFFu;
}

std::string chunk(std::string_view kind, std::string_view body) {
  std::string out;
  test::put(out, static_cast<std::uint32_t>(body.size()), std::endian::big);
  const std::string typed = std::string(kind) + std::string(body);
  out += typed;
  test::put(out, crc32(typed), std::endian::big);
  return out;
}

class BoundedClaimsTest : public test::IoTest {};

TEST_F(BoundedClaimsTest, PngClaimingMorePixelsThanItsBytesIsRefusedUnallocated) {
  std::string ihdr;
  test::put(ihdr, std::uint32_t{30000}, std::endian::big);  // 30000 × 30000 × 2 bytes = 1.8 GB
  test::put(ihdr, std::uint32_t{30000}, std::endian::big);
  ihdr += std::string("\x10\x00\x00\x00\x00", 5);  // 16-bit gray, deflate, no filter, no interlace
  const std::string png = std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", ihdr) +
                          chunk("IDAT", std::string("\x78\x9c\x03\x00\x00\x00\x00\x01", 8)) + chunk("IEND", "");
  try {
    (void)read_depth_png(write("big.png", png));
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("big.png: PNG header: header claims 30000x30000 pixels, more than the"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace hmap
