// Outputs are written atomically: a killed run leaves either the previous
// file or the new one, never a truncated mix, so reruns can trust what exists.
#pragma once

#include <cstddef>
#include <string>

namespace skyfall {

// Writes `content` to a temporary file beside `path`, flushes it to disk and
// renames it over `path`. Creates missing parent folders. Throws Error naming
// the path on failure.
void WriteFileAtomic(const std::string& path, const std::string& content);

// Like WriteFileAtomic, but leaves the file untouched (and its time stamp
// unchanged) when it already holds exactly `content`. Returns true when written.
bool WriteFileIfChanged(const std::string& path, const std::string& content);

// The same for content written in pieces: each Write goes to a temporary
// file beside `path`; Commit flushes it to disk and renames it over `path`.
// Destroyed uncommitted (an error, a throw), the temporary file is removed
// and `path` keeps what it held. Throws Error naming the path on failure.
class AtomicFileWriter {
 public:
  explicit AtomicFileWriter(std::string path);
  ~AtomicFileWriter();
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;
  void Write(const char* data, std::size_t size);
  void Write(const std::string& data) { Write(data.data(), data.size()); }
  // Appends the whole content of the file at `source`.
  void CopyFrom(const std::string& source);
  void Commit();

 private:
  std::string path_, tmp_;
  int fd_ = -1;
};

// Reads a whole text file; throws Error naming the path when it cannot.
std::string ReadTextFile(const std::string& path);

}  // namespace skyfall
