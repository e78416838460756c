// The exit-code contract of every skyfall command and of child tile
// processes, so that batch drivers and cron jobs can tell outcomes apart
// (docs/cli.md lists them for users).
#pragma once

#include "core/stage.h"

namespace skyfall {

constexpr int kExitOk = 0;             // success (also: nothing changed since the last run)
constexpr int kExitBadInput = 1;       // bad input file or option value (the message names it)
constexpr int kExitUsage = 2;          // bad command line (unknown flag, missing argument)
constexpr int kExitInternal = 3;       // a bug or an unexpected system failure
constexpr int kExitDegenerate = 4;     // too little data for a result (e.g. fewer than 2 usable images)
constexpr int kExitPartial = 5;        // `run`: some cities, AOIs or tiles failed, the others finished
constexpr int kExitNothingDone = 6;    // `run`: no AOI could be ingested or reconstructed
constexpr int kExitLocked = 7;         // `run`: another run holds the output folder's lock

// Exit code for a stage outcome: ok and skipped are success.
inline int ExitCodeOf(StageStatus status) {
  switch (status) {
    case StageStatus::kDegenerate: return kExitDegenerate;
    case StageStatus::kFailed: return kExitBadInput;
    default: return kExitOk;
  }
}

}  // namespace skyfall
