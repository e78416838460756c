// Gaussian scenes as Inria 3DGS PLY files (binary little endian): x y z,
// nx ny nz, f_dc_0..2, f_rest_* (channel-major), opacity (logit),
// scale_0..2 (log), rot_0..3 (w first), so SuperSplat, gsplat and OpenSplat
// viewers load them.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>

#include "core/gaussians.h"

namespace skyfall {

// Serialized file content; `sh_degree` 0 or 1 decides how many f_rest_*.
std::string GaussiansToPly(const GaussianCloud& cloud, int sh_degree = 1);
// Atomic write (temporary file + rename).
void WriteGaussiansPly(const std::string& path, const GaussianCloud& cloud, int sh_degree = 1);

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
