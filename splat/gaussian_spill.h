// Records gathered on disk by key (a node of a tile tree, a block of
// ground), so that memory holds a bounded buffer of them whatever their
// total: the city-scale merge and export sort clouds larger than memory
// into pieces they then handle one at a time.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/gaussians.h"

namespace skyfall {

// Fixed-size records by key. A key's records keep the order they were
// added. The folder is emptied on construction (a killed run's leftovers)
// and removed on destruction.
class KeyedSpill {
 public:
  KeyedSpill(std::filesystem::path dir, std::size_t record_bytes, std::size_t budget_bytes);
  ~KeyedSpill();
  KeyedSpill(const KeyedSpill&) = delete;
  KeyedSpill& operator=(const KeyedSpill&) = delete;

  void Add(const std::string& key, const void* record);
  // Appends every buffer to its key's file and frees the buffers.
  void Flush();
  // The keys that hold records, sorted.
  const std::set<std::string>& keys() const { return keys_; }
  std::size_t record_bytes() const { return record_bytes_; }
  // The key's records in the order added (empty for an unknown key).
  std::string Read(const std::string& key);
  void Remove(const std::string& key);

 private:
  std::filesystem::path File(const std::string& key) const { return dir_ / ("k" + key + ".bin"); }

  std::filesystem::path dir_;
  std::size_t record_bytes_, budget_bytes_;
  std::size_t buffered_bytes_ = 0;
  std::unordered_map<std::string, std::string> buffers_;
  std::set<std::string> keys_;
};

// Gaussians in a KeyedSpill, each with a 64-bit tag (the caller's: say, its
// index in the file it came from).
inline constexpr std::size_t kSpilledGaussianBytes = (11 + 3 * kShCoeffsPerChannel) * sizeof(float) + 8;
void SpillGaussian(KeyedSpill& spill, const std::string& key, const GaussianCloud& cloud, std::size_t i,
                   std::uint64_t tag = 0);
// The key's Gaussians in the order added; their tags to `tags` when given.
GaussianCloud ReadSpilledGaussians(KeyedSpill& spill, const std::string& key,
                                   std::vector<std::uint64_t>* tags = nullptr);

}  // namespace skyfall
