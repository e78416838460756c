#include "splat/ply.h"

#include <cmath>
#include <cstring>
#include <map>
#include <sstream>

#include "core/atomic_file.h"
#include "core/error.h"

namespace skyfall {

std::string GaussiansToPly(const GaussianCloud& c, int sh_degree) {
  if (sh_degree != 0 && sh_degree != 1) throw Error("ply", "sh_degree", "must be 0 or 1");
  const int rest = sh_degree == 1 ? 9 : 0;
  std::ostringstream head;
  head << "ply\nformat binary_little_endian 1.0\nelement vertex " << c.size() << "\n";
  for (const char* name : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"})
    head << "property float " << name << "\n";
  for (int k = 0; k < rest; ++k) head << "property float f_rest_" << k << "\n";
  head << "property float opacity\n";
  for (int k = 0; k < 3; ++k) head << "property float scale_" << k << "\n";
  for (int k = 0; k < 4; ++k) head << "property float rot_" << k << "\n";
  head << "end_header\n";
  std::string out = head.str();
  const int floats = 9 + rest + 1 + 3 + 4;
  std::vector<float> row(floats);
  const size_t header_size = out.size();
  out.resize(header_size + c.size() * floats * sizeof(float));
  char* dst = out.data() + header_size;
  for (size_t i = 0; i < c.size(); ++i) {
    int k = 0;
    for (int a = 0; a < 3; ++a) row[k++] = c.means[i][a];
    for (int a = 0; a < 3; ++a) row[k++] = 0.0f;  // normals: unused by 3DGS viewers
    for (int ch = 0; ch < 3; ++ch) row[k++] = c.sh[i][ch * 4];
    for (int ch = 0; ch < 3 && rest; ++ch)
      for (int j = 1; j < 4; ++j) row[k++] = c.sh[i][ch * 4 + j];
    row[k++] = c.opacity_logits[i];
    for (int a = 0; a < 3; ++a) row[k++] = c.log_scales[i][a];
    for (int a = 0; a < 4; ++a) row[k++] = c.rotations[i][a];
    std::memcpy(dst, row.data(), floats * sizeof(float));  // x86-64 is little endian
    dst += floats * sizeof(float);
  }
  return out;
}

void WriteGaussiansPly(const std::string& path, const GaussianCloud& cloud, int sh_degree) {
  WriteFileAtomic(path, GaussiansToPly(cloud, sh_degree));
}

GaussianCloud ReadGaussiansPly(const std::string& path) { return ParseGaussiansPly(ReadTextFile(path), path); }

GaussianCloud ParseGaussiansPly(const std::string& data, const std::string& path) {
  const size_t end = data.find("end_header\n");
  if (data.rfind("ply\n", 0) != 0 || end == std::string::npos) {
    throw Error("ply", path, "not a PLY file (missing 'ply' magic or 'end_header')");
  }
  std::istringstream header(data.substr(0, end));
  std::string line, format;
  size_t count = 0;
  bool in_vertex = false;
  std::vector<std::string> props;
  while (std::getline(header, line)) {
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (word == "format") {
      ls >> format;
    } else if (word == "element") {
      std::string name;
      ls >> name >> count;
      in_vertex = name == "vertex";
      if (!in_vertex && count > 0) throw Error("ply", path, "unexpected element '" + name + "' (only vertex)");
    } else if (word == "property" && in_vertex) {
      std::string type, name;
      ls >> type >> name;
      if (type != "float" && type != "float32") {
        throw Error("ply", path, "property '" + name + "' has type '" + type + "', expected float");
      }
      props.push_back(name);
    }
  }
  if (format != "binary_little_endian" && format != "ascii") {
    throw Error("ply", path, "format '" + format + "' is not supported (binary_little_endian or ascii)");
  }
  std::map<std::string, int> col;
  for (size_t k = 0; k < props.size(); ++k) col[props[k]] = static_cast<int>(k);
  auto need = [&](const std::string& name) {
    const auto it = col.find(name);
    if (it == col.end()) throw Error("ply", path, "property '" + name + "' is missing (not an Inria 3DGS PLY)");
    return it->second;
  };
  int rest_count = 0;
  while (col.count("f_rest_" + std::to_string(rest_count))) ++rest_count;
  if (rest_count % 3 != 0) throw Error("ply", path, "f_rest_* count " + std::to_string(rest_count) + " is not 3 * k");
  const int rest_per_channel = rest_count / 3;
  const char* body = data.data() + end + std::strlen("end_header\n");
  const size_t body_size = data.size() - (end + std::strlen("end_header\n"));
  // The declared count must fit the data before anything is allocated: a
  // binary value takes 4 bytes, an ASCII one at least 2 characters.
  const size_t min_value_bytes = format == "binary_little_endian" ? sizeof(float) : 2;
  if (props.empty() || count > body_size / min_value_bytes / props.size() + 1) {
    throw Error("ply", path, "declares " + std::to_string(count) + " vertices of " + std::to_string(props.size()) +
                                 " properties, more than its " + std::to_string(body_size) + " bytes of data hold");
  }
  std::vector<float> values(count * props.size());
  if (format == "binary_little_endian") {
    if (body_size < values.size() * sizeof(float)) {
      throw Error("ply", path, "truncated: " + std::to_string(body_size) + " bytes of data, " +
                                   std::to_string(values.size() * sizeof(float)) + " expected");
    }
    if (!values.empty()) std::memcpy(values.data(), body, values.size() * sizeof(float));
  } else {
    std::istringstream in(std::string(body, body_size));
    for (size_t k = 0; k < values.size(); ++k)
      if (!(in >> values[k])) throw Error("ply", path, "truncated ASCII data at value " + std::to_string(k));
  }
  GaussianCloud c;
  c.resize(count);
  // Every property by its own name: a header may list them in any order.
  const int px = need("x"), py = need("y"), pz = need("z");
  const int dc[3] = {need("f_dc_0"), need("f_dc_1"), need("f_dc_2")};
  const int op = need("opacity");
  const int sc[3] = {need("scale_0"), need("scale_1"), need("scale_2")};
  const int rot[4] = {need("rot_0"), need("rot_1"), need("rot_2"), need("rot_3")};
  std::vector<int> rest(rest_count);
  for (int k = 0; k < rest_count; ++k) rest[k] = col["f_rest_" + std::to_string(k)];
  for (size_t i = 0; i < count; ++i) {
    const float* v = &values[i * props.size()];
    c.means[i] = Eigen::Vector3f(v[px], v[py], v[pz]);
    c.sh[i].fill(0.0f);
    for (int ch = 0; ch < 3; ++ch) {
      c.sh[i][ch * 4] = v[dc[ch]];
      for (int j = 1; j < 4 && j <= rest_per_channel; ++j) c.sh[i][ch * 4 + j] = v[rest[ch * rest_per_channel + (j - 1)]];
    }
    c.opacity_logits[i] = v[op];
    c.log_scales[i] = Eigen::Vector3f(v[sc[0]], v[sc[1]], v[sc[2]]);
    c.rotations[i] = Eigen::Vector4f(v[rot[0]], v[rot[1]], v[rot[2]], v[rot[3]]);
    for (int a = 0; a < 3; ++a) {
      if (!std::isfinite(c.means[i][a]) || !std::isfinite(c.log_scales[i][a])) {
        throw Error("ply", path, "Gaussian " + std::to_string(i) + " has a non-finite position or scale");
      }
    }
  }
  return c;
}

}  // namespace skyfall
