// Gaussian scenes as Inria 3DGS PLY files (binary little endian): x y z,
// nx ny nz, f_dc_0..2, f_rest_* (channel-major), opacity (logit),
// scale_0..2 (log), rot_0..3 (w first), so SuperSplat, gsplat and OpenSplat
// viewers load them.
#pragma once

#include <string>

#include "core/gaussians.h"

namespace skyfall {

// Serialized file content; `sh_degree` 0 or 1 decides how many f_rest_*.
std::string GaussiansToPly(const GaussianCloud& cloud, int sh_degree = 1);
// Atomic write (temporary file + rename).
void WriteGaussiansPly(const std::string& path, const GaussianCloud& cloud, int sh_degree = 1);

// Reads Inria-layout PLY (binary little endian or ASCII) of any SH degree;
// coefficients beyond degree 1 are dropped. Throws Error("ply", path, ...)
// naming the missing property or the bad header line.
GaussianCloud ReadGaussiansPly(const std::string& path);
// The same from the file's bytes; `path` names it in errors.
GaussianCloud ParseGaussiansPly(const std::string& data, const std::string& path);

}  // namespace skyfall
