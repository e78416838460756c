#include "core/stage.h"

namespace skyfall {

const char* ToString(StageStatus status) {
  switch (status) {
    case StageStatus::kOk: return "ok";
    case StageStatus::kSkipped: return "skipped";
    case StageStatus::kDegenerate: return "degenerate";
    case StageStatus::kFailed: return "failed";
  }
  return "unknown";
}

}  // namespace skyfall
