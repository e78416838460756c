#include "core/atomic_file.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "core/error.h"

namespace skyfall {
namespace {

namespace fs = std::filesystem;

fs::path TempDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("skyfall_atomic_" + name);
  fs::remove_all(dir);
  return dir;
}

TEST(AtomicFile, WritesCreatesParentsAndReplaces) {
  const fs::path dir = TempDir("replace");
  const std::string path = (dir / "a" / "b.json").string();
  WriteFileAtomic(path, "first");
  EXPECT_EQ(ReadTextFile(path), "first");
  WriteFileAtomic(path, "second");
  EXPECT_EQ(ReadTextFile(path), "second");
  // No temporary file is left beside the target.
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir / "a")) entries += e.is_regular_file();
  EXPECT_EQ(entries, 1);
  fs::remove_all(dir);
}

TEST(AtomicFile, FailureNamesThePathAndKeepsTheOldFile) {
  const fs::path dir = TempDir("fail");
  const std::string path = (dir / "keep.txt").string();
  WriteFileAtomic(path, "old");
  // A folder where the file should go: rename over it fails.
  const std::string blocked = (dir / "sub").string();
  fs::create_directories(dir / "sub" / "x");
  try {
    WriteFileAtomic(blocked, "new");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("sub"), std::string::npos);
  }
  EXPECT_EQ(ReadTextFile(path), "old");
  EXPECT_THROW(ReadTextFile((dir / "missing").string()), Error);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace skyfall
