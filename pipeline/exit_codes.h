// The exit-code contract of every skyfall command and of child tile
// processes, so that batch drivers and cron jobs can tell outcomes apart.
#pragma once

#include "core/stage.h"

namespace skyfall {

constexpr int kExitOk = 0;          // success (also: nothing left to do)
constexpr int kExitBadInput = 1;    // bad input or options, or nothing could be processed
constexpr int kExitInternal = 3;    // a bug or an unexpected system failure
constexpr int kExitDegenerate = 4;  // too little data for a result (e.g. fewer than 2 usable images)

// Exit code for a stage outcome: ok and skipped are success.
inline int ExitCodeOf(StageStatus status) {
  switch (status) {
    case StageStatus::kDegenerate: return kExitDegenerate;
    case StageStatus::kFailed: return kExitBadInput;
    default: return kExitOk;
  }
}

}  // namespace skyfall
