// SHA-256 content hashes (lower-case hex), for the inputs a rerun compares
// and for STAC's file:checksum.
#pragma once

#include <string>

namespace skyfall {

std::string Sha256Hex(const std::string& bytes);

// The hash of a file's content, read in blocks. Throws Error naming the path
// when it cannot be read.
std::string Sha256FileHex(const std::string& path);

// The multihash form STAC's file:checksum uses: "1220" (SHA2-256, 32 bytes)
// followed by the hex digest.
inline std::string Sha256Multihash(const std::string& hex) { return "1220" + hex; }

}  // namespace skyfall
