// The one error type of the project. Bad input and broken contracts throw it;
// expected outcomes (too few matches, an empty tile) are statuses in a
// StageReport instead. The message always names where the problem is (stage,
// file or image) and which value is wrong, so a user can fix the input.
#pragma once

#include <stdexcept>
#include <string>

namespace skyfall {

class Error : public std::runtime_error {
 public:
  // `stage`: the stage or module ("rpc", "ingest", ...).
  // `subject`: the file, image, tile or field the problem is about (may be empty).
  // `what`: what is wrong, with the offending value.
  Error(std::string stage, std::string subject, const std::string& what)
      : std::runtime_error(Compose(stage, subject, what)),
        stage_(std::move(stage)),
        subject_(std::move(subject)),
        detail_(what) {}

  const std::string& stage() const { return stage_; }
  const std::string& subject() const { return subject_; }
  const std::string& detail() const { return detail_; }  // the `what` part alone

  // Same error with `outer` (typically a file path) placed in front of the
  // subject. Used by readers that parse a buffer and only later learn which
  // file it came from: "rpc: a.tif: LINE_OFF: is missing".
  Error Within(const std::string& outer) const;

 private:
  static std::string Compose(const std::string& stage, const std::string& subject,
                             const std::string& what);
  std::string stage_;
  std::string subject_;
  std::string detail_;
};

}  // namespace skyfall
