// Gaussian scenes as Inria 3DGS PLY files (binary little endian): x y z,
// nx ny nz, f_dc_0..2, f_rest_* (channel-major), opacity (logit),
// scale_0..2 (log), rot_0..3 (w first), so SuperSplat, gsplat and OpenSplat
// viewers load them.
#pragma once

#include <Eigen/Core>
#include <fstream>
#include <functional>
#include <string>

#include "core/gaussians.h"

namespace skyfall {

// Serialized file content; `sh_degree` 0 or 1 decides how many f_rest_*.
std::string GaussiansToPly(const GaussianCloud& cloud, int sh_degree = 1);
// Atomic write (temporary file + rename).
void WriteGaussiansPly(const std::string& path, const GaussianCloud& cloud, int sh_degree = 1);

// Writes a PLY a Gaussian at a time, for clouds larger than memory: the
// records go to `path`.body.tmp, and Finish writes the header (which needs
// the count) and the records to `path` atomically: the same bytes as
// WriteGaussiansPly of the same Gaussians. Dropped unfinished (a throw), it
// removes its temporary file and leaves `path` as it was.
class GaussiansPlyWriter {
 public:
  explicit GaussiansPlyWriter(std::string path, int sh_degree = 1);
  ~GaussiansPlyWriter();
  GaussiansPlyWriter(const GaussiansPlyWriter&) = delete;
  GaussiansPlyWriter& operator=(const GaussiansPlyWriter&) = delete;
  void Add(const GaussianCloud& cloud, std::size_t i);
  void AddAll(const GaussianCloud& cloud);
  std::size_t count() const { return count_; }
  void Finish();

 private:
  void FlushBuffer();
  std::string path_, body_path_;
  int rest_;
  std::size_t count_ = 0;
  std::string buffer_;
  std::ofstream body_;
  bool finished_ = false;
};

// Which Gaussians a read keeps, by centre [m] and log standard deviations.
using GaussianFilter = std::function<bool(const Eigen::Vector3f& mean, const Eigen::Vector3f& log_scale)>;

// Reads Inria-layout PLY (binary little endian or ASCII) of any SH degree;
// coefficients beyond degree 1 are dropped. With `keep`, only the Gaussians
// it takes, in file order; the file is read a chunk at a time, so memory
// holds what is kept and one chunk. Throws Error("ply", path, ...) naming
// the missing property, the bad header line or the truncation.
GaussianCloud ReadGaussiansPly(const std::string& path, const GaussianFilter& keep = {});
// Reads the file a chunk (65,536 Gaussians) at a time and hands each chunk to
// `visit`, in file order; memory holds one chunk, whatever the file's size.
// Throws as ReadGaussiansPly.
using GaussianChunkVisitor = std::function<void(const GaussianCloud& chunk)>;
void ForEachGaussiansPlyChunk(const std::string& path, const GaussianChunkVisitor& visit);
// The same from the file's bytes; `path` names it in errors.
GaussianCloud ParseGaussiansPly(const std::string& data, const std::string& path);

}  // namespace skyfall
