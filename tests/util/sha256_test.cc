#include "util/sha256.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "util/io.h"

namespace topocal::util {
namespace {

// FIPS 180-2 Appendix B.1 and the digest of the empty message (published test vectors).
TEST(Sha256, KnownVectors) {
  EXPECT_EQ(util::Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(util::Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(Sha256, FileDigestEqualsBytesDigestAndMissingFileIsNamed) {
  const auto path = (std::filesystem::temp_directory_path() / "topocal_sha256_test.bin").string();
  util::WriteFileAtomic(path, std::string("abc"));
  EXPECT_EQ(util::Sha256HexOfFile(path), util::Sha256Hex("abc"));
  std::filesystem::remove(path);
  try {
    util::Sha256HexOfFile(path);
    FAIL() << "no exception";
  } catch (const util::InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos);
  }
}

}  // namespace
}  // namespace topocal::util
