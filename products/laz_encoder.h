// LAZ compression (LASzip 1.4, "layered chunked", item versions 3) of the
// point records this project writes: LAS 1.4 point data record format 7 with
// every point return 1 of 1, scanner channel 0, no flags, intensity, user
// data, scan angle, point source or GPS time. Only X, Y, Z, the class and
// the colour vary, and the encoder is written for that record alone, so the
// coding of the constant fields (which LASzip spends no layer bytes on when
// nothing changes) is implied rather than carried.
//
// The entropy coder is the one LASzip specifies (Amir Said's FastAC with
// periodically updated adaptive models, LASzip's integer corrector coding);
// the context choices follow LASzip's POINT14 v3 and RGB14 v3 items. No LAZ
// encoder is packaged by Debian bookworm or npm, hence this one; the tests
// read its output back with two independent decoders (laz-rs and laz-perf,
// from npm).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace skyfall {

// One format-7 record as stored: coordinates already scaled to integers.
struct LazRecord {
  std::array<std::int32_t, 3> xyz{};
  std::uint8_t classification = 1;
  std::array<std::uint16_t, 3> rgb{};
};

// The uncompressed 36-byte format-7 record (also the first point of every
// LAZ chunk, which LASzip stores raw).
std::string RawRecord7(const LazRecord& r);

// One self-contained LAZ chunk holding `records` (at least one): the first
// record raw, the point count, the byte count of each layer, then the
// layers. Chunks decode independently, which COPC relies on (one chunk per
// octree node).
std::string EncodeLazChunk(const std::vector<LazRecord>& records);

// Where a chunk lies: its point count and its size in bytes.
struct LazChunkEntry {
  std::uint32_t points = 0;
  std::uint32_t bytes = 0;
};

// The chunk table LASzip appends after the last chunk: version 0, the chunk
// count, then the entropy-coded sizes in bytes, preceded by each chunk's
// point count when chunks vary in size.
std::string EncodeLazChunkTable(const std::vector<LazChunkEntry>& chunks, bool variable_size);

// Chunks of a fixed size in points, the kind every LAZ 1.4 reader handles
// (laz-rs before 0.6 reads no other); COPC needs variable ones.
constexpr std::uint32_t kLazFixedChunkPoints = 50000;
constexpr std::uint32_t kLazVariableChunks = 0xFFFFFFFFu;

// The payload of the "laszip encoded" VLR (record 22204) for format 7,
// layered compression, chunks of `chunk_points` (or kLazVariableChunks).
std::string LaszipVlrPayload(std::uint32_t chunk_points);

constexpr char kLaszipUserId[] = "laszip encoded";
constexpr std::uint16_t kLaszipRecordId = 22204;
// Bit 7 of the header's point data format marks compressed records.
constexpr std::uint8_t kLazFormatBit = 0x80;

}  // namespace skyfall
