#include "core/sha256.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/error.h"

namespace skyfall {
namespace {

// FIPS 180-2 test vectors.
TEST(Sha256, KnownVectors) {
  EXPECT_EQ(Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(Sha256Multihash(Sha256Hex("abc")).substr(0, 6), "1220ba");
}

TEST(Sha256, FileInBlocksEqualsBytes) {
  const auto path = std::filesystem::temp_directory_path() / "skyfall_sha256_test.bin";
  std::string bytes;
  for (int i = 0; i < 200000; ++i) bytes += static_cast<char>(i * 7);  // more than one 64 KiB block
  std::ofstream(path, std::ios::binary) << bytes;
  EXPECT_EQ(Sha256FileHex(path.string()), Sha256Hex(bytes));
  EXPECT_THROW(Sha256FileHex((path.string() + ".missing")), Error);
}

}  // namespace
}  // namespace skyfall
