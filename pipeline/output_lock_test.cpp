#include "pipeline/output_lock.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include "tests/test_support.h"

namespace skyfall {
namespace {

using testing::ScratchDir;

TEST(OutputLock, SecondHolderIsRefusedAndToldWhoHoldsIt) {
  const auto dir = ScratchDir("out");
  LockHolder holder;
  auto first = OutputLock::Acquire(dir.string(), 0, &holder);
  ASSERT_TRUE(first.has_value());
  // flock conflicts between open file descriptions, even in one process.
  auto second = OutputLock::Acquire(dir.string(), 0, &holder);
  EXPECT_FALSE(second.has_value());
  EXPECT_EQ(holder.pid, getpid());
  EXPECT_EQ(holder.started_utc.size(), 20u) << holder.started_utc;  // 2026-11-23T18:00:00Z
  EXPECT_NE(DescribeHolder(holder).find("PID " + std::to_string(getpid())), std::string::npos);
  first.reset();
  EXPECT_TRUE(OutputLock::Acquire(dir.string(), 0, &holder).has_value());
}

TEST(OutputLock, WaitsForTheHolderToFinish) {
  const auto dir = ScratchDir("out");
  LockHolder holder;
  auto first = OutputLock::Acquire(dir.string(), 0, &holder);
  ASSERT_TRUE(first.has_value());
  std::thread release([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    first.reset();
  });
  auto waited = OutputLock::Acquire(dir.string(), 30, &holder);
  release.join();
  EXPECT_TRUE(waited.has_value());
}

TEST(OutputLock, KilledHolderReleasesTheLock) {
  const auto dir = ScratchDir("out");
  int ready[2];
  ASSERT_EQ(pipe(ready), 0);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    LockHolder unused;
    auto lock = OutputLock::Acquire(dir.string(), 0, &unused);
    const char byte = lock ? 1 : 0;
    [[maybe_unused]] auto n = write(ready[1], &byte, 1);
    pause();  // killed by the parent, never unlocks by itself
    _exit(0);
  }
  char byte = 0;
  ASSERT_EQ(read(ready[0], &byte, 1), 1);
  ASSERT_EQ(byte, 1);
  LockHolder holder;
  EXPECT_FALSE(OutputLock::Acquire(dir.string(), 0, &holder).has_value());
  EXPECT_EQ(holder.pid, child);
  kill(child, SIGKILL);
  waitpid(child, nullptr, 0);
  EXPECT_TRUE(OutputLock::Acquire(dir.string(), 0, &holder).has_value());
  close(ready[0]);
  close(ready[1]);
}

}  // namespace
}  // namespace skyfall
