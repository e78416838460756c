// SPZ v2 (Niantic's compressed Gaussian splats, as the glTF extension
// KHR_gaussian_splatting_compression_spz_2 carries them): a gzip stream of a
// 16-byte header (magic 0x5053474e "NGSP", version 2, point count, SH degree,
// fractional bits, flags) and, attribute by attribute, positions as 24-bit
// fixed point, opacities, DC colours, log scales, rotations (x, y, z of the
// unit quaternion with w >= 0) and degree-1 SH, each quantized to bytes.
// Values are stored in the frame they are given in (no axis flips): the
// glTF content keeps the scene's ENU (z-up) positions and its node turns
// them y-up, so a decoder that leaves coordinates as stored ("UNSPECIFIED")
// gets them back.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/gaussians.h"

namespace skyfall {

inline constexpr std::uint32_t kSpzMagic = 0x5053474e;
inline constexpr std::uint32_t kSpzVersion = 2;
inline constexpr double kSpzColourScale = 0.15;  // DC coefficient -> byte: dc * 0.15 * 255 + 127.5

// The fractional bits that fit every coordinate of `cloud` into 24-bit signed
// fixed point (at most `max_bits`): the quantization step is 2^-bits metres.
int SpzFractionalBits(const GaussianCloud& cloud, int max_bits = 16);

// Encodes `cloud` (SH degree 1). Throws Error when a coordinate cannot be
// represented (|x| >= 2^23 m).
std::vector<std::uint8_t> EncodeSpz(const GaussianCloud& cloud, int fractional_bits);

// Decodes an SPZ v2 stream into a cloud (rotations unit, w >= 0). Throws
// Error naming `subject` for a malformed stream.
GaussianCloud DecodeSpz(const std::vector<std::uint8_t>& bytes, const std::string& subject, int* fractional_bits);

}  // namespace skyfall
