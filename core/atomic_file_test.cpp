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

TEST(AtomicFile, AWriterInPiecesShowsNothingUntilCommitted) {
  const fs::path dir = TempDir("pieces");
  const std::string path = (dir / "out.bin").string();
  const std::string source = (dir / "body.bin").string();
  WriteFileAtomic(path, "old");
  WriteFileAtomic(source, std::string(3 << 20, 'b'));  // over the copy's 1 MB buffer
  {
    AtomicFileWriter out(path);
    out.Write("head");
    out.CopyFrom(source);
    EXPECT_EQ(ReadTextFile(path), "old");
  }  // dropped uncommitted, as when a throw leaves the scope
  EXPECT_EQ(ReadTextFile(path), "old");
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir)) entries += e.is_regular_file();
  EXPECT_EQ(entries, 2);  // no temporary file left
  AtomicFileWriter out(path);
  out.Write("head");
  out.CopyFrom(source);
  out.Commit();
  EXPECT_EQ(ReadTextFile(path), "head" + std::string(3 << 20, 'b'));
  EXPECT_THROW(out.Write("late"), Error);
  EXPECT_THROW(out.CopyFrom((dir / "missing").string()), Error);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace skyfall
