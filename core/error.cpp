#include "core/error.h"

namespace skyfall {

std::string Error::Compose(const std::string& stage, const std::string& subject,
                           const std::string& what) {
  std::string msg = stage;
  if (!subject.empty()) msg += ": " + subject;
  msg += ": " + what;
  return msg;
}

Error Error::Within(const std::string& outer) const {
  return Error(stage_, subject_.empty() ? outer : outer + ": " + subject_, detail_);
}

}  // namespace skyfall
