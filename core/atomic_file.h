// Outputs are written atomically: a killed run leaves either the previous
// file or the new one, never a truncated mix, so reruns can trust what exists.
#pragma once

#include <string>

namespace skyfall {

// Writes `content` to a temporary file beside `path`, flushes it to disk and
// renames it over `path`. Creates missing parent folders. Throws Error naming
// the path on failure.
void WriteFileAtomic(const std::string& path, const std::string& content);

// Like WriteFileAtomic, but leaves the file untouched (and its time stamp
// unchanged) when it already holds exactly `content`. Returns true when written.
bool WriteFileIfChanged(const std::string& path, const std::string& content);

// Reads a whole text file; throws Error naming the path when it cannot.
std::string ReadTextFile(const std::string& path);

}  // namespace skyfall
