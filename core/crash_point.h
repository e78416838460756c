// Fault injection for the crash-safety test (tests/cli_test.cpp,
// Cli.KilledRunsResumeToTheSameProducts): when the environment variable
// SKYFALL_CRASH_AT names a point the run reaches, the run is killed there
// with SIGKILL, as a power cut or the OOM killer would. In a tile process of
// the local executor the whole run (its parent) is killed. Without the
// variable a crash point costs one cached pointer test.
#pragma once

namespace skyfall {

inline constexpr const char* kCrashAtEnv = "SKYFALL_CRASH_AT";

// Points: "sfm", "dense", "train:<iteration>", "idu", "tile", "merge", "dsm",
// "dsm_written", "report", "stac", "summary".
void CrashPoint(const char* name);
void CrashPoint(const char* name, long number);  // "<name>:<number>"

}  // namespace skyfall
