#include "splat/ply.h"

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <cstring>
#include <map>
#include <sstream>

#include "core/atomic_file.h"
#include "core/error.h"

namespace skyfall {

namespace {

int RestCoefficients(int sh_degree) {
  if (sh_degree != 0 && sh_degree != 1) throw Error("ply", "sh_degree", "must be 0 or 1");
  return sh_degree == 1 ? 9 : 0;
}

std::string PlyHeader(std::size_t count, int rest) {
  std::ostringstream head;
  head << "ply\nformat binary_little_endian 1.0\nelement vertex " << count << "\n";
  for (const char* name : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"})
    head << "property float " << name << "\n";
  for (int k = 0; k < rest; ++k) head << "property float f_rest_" << k << "\n";
  head << "property float opacity\n";
  for (int k = 0; k < 3; ++k) head << "property float scale_" << k << "\n";
  for (int k = 0; k < 4; ++k) head << "property float rot_" << k << "\n";
  head << "end_header\n";
  return head.str();
}

std::size_t RecordBytes(int rest) { return (9 + rest + 1 + 3 + 4) * sizeof(float); }

// Gaussian i's record at `dst` (RecordBytes(rest) bytes).
void EncodeRecord(const GaussianCloud& c, std::size_t i, int rest, char* dst) {
  std::array<float, 9 + 9 + 1 + 3 + 4> row;
  int k = 0;
  for (int a = 0; a < 3; ++a) row[k++] = c.means[i][a];
  for (int a = 0; a < 3; ++a) row[k++] = 0.0f;  // normals: unused by 3DGS viewers
  for (int ch = 0; ch < 3; ++ch) row[k++] = c.sh[i][ch * 4];
  for (int ch = 0; ch < 3 && rest; ++ch)
    for (int j = 1; j < 4; ++j) row[k++] = c.sh[i][ch * 4 + j];
  row[k++] = c.opacity_logits[i];
  for (int a = 0; a < 3; ++a) row[k++] = c.log_scales[i][a];
  for (int a = 0; a < 4; ++a) row[k++] = c.rotations[i][a];
  std::memcpy(dst, row.data(), k * sizeof(float));  // x86-64 is little endian
}

}  // namespace

std::string GaussiansToPly(const GaussianCloud& c, int sh_degree) {
  const int rest = RestCoefficients(sh_degree);
  std::string out = PlyHeader(c.size(), rest);
  const std::size_t header_size = out.size(), record = RecordBytes(rest);
  out.resize(header_size + c.size() * record);
  for (std::size_t i = 0; i < c.size(); ++i) EncodeRecord(c, i, rest, out.data() + header_size + i * record);
  return out;
}

void WriteGaussiansPly(const std::string& path, const GaussianCloud& cloud, int sh_degree) {
  WriteFileAtomic(path, GaussiansToPly(cloud, sh_degree));
}

GaussiansPlyWriter::GaussiansPlyWriter(std::string path, int sh_degree)
    : path_(std::move(path)), body_path_(path_ + ".body.tmp"), rest_(RestCoefficients(sh_degree)) {
  std::error_code ec;
  const std::filesystem::path parent = std::filesystem::path(path_).parent_path();
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  body_.open(body_path_, std::ios::binary | std::ios::trunc);
  if (!body_) throw Error("ply", body_path_, "cannot be created");
}

GaussiansPlyWriter::~GaussiansPlyWriter() {
  if (finished_) return;
  body_.close();
  std::error_code ec;
  std::filesystem::remove(body_path_, ec);
}

void GaussiansPlyWriter::Add(const GaussianCloud& cloud, std::size_t i) {
  if (finished_) throw Error("ply", path_, "written after it was finished");
  const std::size_t record = RecordBytes(rest_);
  buffer_.resize(buffer_.size() + record);
  EncodeRecord(cloud, i, rest_, buffer_.data() + buffer_.size() - record);
  ++count_;
  constexpr std::size_t kBufferBytes = 4 << 20;
  if (buffer_.size() >= kBufferBytes) FlushBuffer();
}

void GaussiansPlyWriter::AddAll(const GaussianCloud& cloud) {
  for (std::size_t i = 0; i < cloud.size(); ++i) Add(cloud, i);
}

void GaussiansPlyWriter::FlushBuffer() {
  body_.write(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
  if (!body_) throw Error("ply", body_path_, "cannot be written (disk full?)");
  buffer_.clear();
}

void GaussiansPlyWriter::Finish() {
  if (finished_) throw Error("ply", path_, "finished twice");
  FlushBuffer();
  body_.close();
  if (!body_) throw Error("ply", body_path_, "cannot be written (disk full?)");
  AtomicFileWriter out(path_);
  out.Write(PlyHeader(count_, rest_));
  out.CopyFrom(body_path_);
  out.Commit();
  finished_ = true;
  std::filesystem::remove(body_path_);
}

namespace {

// What a PLY header declares: the format, the vertex count, the properties
// in order, and where the Inria fields sit among them.
struct PlyLayout {
  std::string format;
  std::size_t count = 0;
  std::vector<std::string> props;
  int px = 0, py = 0, pz = 0, op = 0;
  int dc[3] = {0, 0, 0}, sc[3] = {0, 0, 0}, rot[4] = {0, 0, 0, 0};
  std::vector<int> rest;  // channel-major f_rest_* columns
  int rest_per_channel = 0;
};

// A header is a few kB; a file without `end_header` in its first MB is not a PLY.
constexpr std::size_t kMaxHeaderBytes = 1 << 20;

PlyLayout ReadHeader(std::istream& in, const std::string& path) {
  auto not_ply = [&] { return Error("ply", path, "not a PLY file (missing 'ply' magic or 'end_header')"); };
  std::string line;
  if (!std::getline(in, line) || line != "ply") throw not_ply();
  PlyLayout l;
  bool in_vertex = false, ended = false;
  std::size_t header_bytes = line.size() + 1;
  while (!ended && std::getline(in, line)) {
    header_bytes += line.size() + 1;
    if (header_bytes > kMaxHeaderBytes) break;
    if (in.eof()) break;  // the last line has no newline: the header never ended
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (word == "end_header") {
      ended = line == "end_header";
    } else if (word == "format") {
      ls >> l.format;
    } else if (word == "element") {
      std::string name;
      ls >> name >> l.count;
      in_vertex = name == "vertex";
      if (!in_vertex && l.count > 0) throw Error("ply", path, "unexpected element '" + name + "' (only vertex)");
    } else if (word == "property" && in_vertex) {
      std::string type, name;
      ls >> type >> name;
      if (type != "float" && type != "float32") {
        throw Error("ply", path, "property '" + name + "' has type '" + type + "', expected float");
      }
      l.props.push_back(name);
    }
  }
  if (!ended) throw not_ply();
  if (l.format != "binary_little_endian" && l.format != "ascii") {
    throw Error("ply", path, "format '" + l.format + "' is not supported (binary_little_endian or ascii)");
  }
  std::map<std::string, int> col;
  for (std::size_t k = 0; k < l.props.size(); ++k) col[l.props[k]] = static_cast<int>(k);
  auto need = [&](const std::string& name) {
    const auto it = col.find(name);
    if (it == col.end()) throw Error("ply", path, "property '" + name + "' is missing (not an Inria 3DGS PLY)");
    return it->second;
  };
  int rest_count = 0;
  while (col.count("f_rest_" + std::to_string(rest_count))) ++rest_count;
  if (rest_count % 3 != 0) throw Error("ply", path, "f_rest_* count " + std::to_string(rest_count) + " is not 3 * k");
  l.rest_per_channel = rest_count / 3;
  // Every property by its own name: a header may list them in any order.
  l.px = need("x"), l.py = need("y"), l.pz = need("z");
  for (int c = 0; c < 3; ++c) l.dc[c] = need("f_dc_" + std::to_string(c));
  l.op = need("opacity");
  for (int a = 0; a < 3; ++a) l.sc[a] = need("scale_" + std::to_string(a));
  for (int a = 0; a < 4; ++a) l.rot[a] = need("rot_" + std::to_string(a));
  for (int k = 0; k < rest_count; ++k) l.rest.push_back(col["f_rest_" + std::to_string(k)]);
  return l;
}

// Appends the vertex `v` (one value per property) to `c` when `keep` takes it.
void AppendVertex(const PlyLayout& l, const float* v, std::size_t index, const GaussianFilter& keep,
                  const std::string& path, GaussianCloud* c) {
  const Eigen::Vector3f mean(v[l.px], v[l.py], v[l.pz]);
  const Eigen::Vector3f log_scale(v[l.sc[0]], v[l.sc[1]], v[l.sc[2]]);
  if (!mean.allFinite() || !log_scale.allFinite()) {
    throw Error("ply", path, "Gaussian " + std::to_string(index) + " has a non-finite position or scale");
  }
  if (keep && !keep(mean, log_scale)) return;
  std::array<float, 3 * kShCoeffsPerChannel> sh{};
  for (int ch = 0; ch < 3; ++ch) {
    sh[ch * 4] = v[l.dc[ch]];
    for (int j = 1; j < 4 && j <= l.rest_per_channel; ++j) sh[ch * 4 + j] = v[l.rest[ch * l.rest_per_channel + (j - 1)]];
  }
  c->means.push_back(mean);
  c->log_scales.push_back(log_scale);
  c->rotations.emplace_back(v[l.rot[0]], v[l.rot[1]], v[l.rot[2]], v[l.rot[3]]);
  c->opacity_logits.push_back(v[l.op]);
  c->sh.push_back(sh);
}

// The vertices after the header, a chunk at a time, so that memory holds the
// kept Gaussians and one chunk, never the whole file.
// With `visit`, each chunk's kept Gaussians are handed to it and dropped, and
// the returned cloud is empty.
GaussianCloud ReadBody(std::istream& in, std::size_t body_size, const PlyLayout& l, const GaussianFilter& keep,
                       const std::string& path, const GaussianChunkVisitor& visit = {}) {
  const std::size_t n_props = l.props.size();
  // The declared count must fit the data before anything is allocated: a
  // binary value takes 4 bytes, an ASCII one at least 2 characters.
  const bool binary = l.format == "binary_little_endian";
  const std::size_t min_value_bytes = binary ? sizeof(float) : 2;
  if (n_props == 0 || l.count > body_size / min_value_bytes / n_props + 1) {
    throw Error("ply", path, "declares " + std::to_string(l.count) + " vertices of " + std::to_string(n_props) +
                                 " properties, more than its " + std::to_string(body_size) + " bytes of data hold");
  }
  if (binary && body_size < l.count * n_props * sizeof(float)) {
    throw Error("ply", path, "truncated: " + std::to_string(body_size) + " bytes of data, " +
                                 std::to_string(l.count * n_props * sizeof(float)) + " expected");
  }
  GaussianCloud c;
  if (!keep && !visit) {
    c.means.reserve(l.count), c.log_scales.reserve(l.count), c.rotations.reserve(l.count);
    c.opacity_logits.reserve(l.count), c.sh.reserve(l.count);
  }
  constexpr std::size_t kChunkVertices = 1 << 16;
  std::vector<float> values(std::min(l.count, kChunkVertices) * n_props);
  for (std::size_t first = 0; first < l.count; first += kChunkVertices) {
    const std::size_t n = std::min(kChunkVertices, l.count - first);
    if (binary) {
      in.read(reinterpret_cast<char*>(values.data()), static_cast<std::streamsize>(n * n_props * sizeof(float)));
      if (static_cast<std::size_t>(in.gcount()) != n * n_props * sizeof(float))
        throw Error("ply", path, "truncated at vertex " + std::to_string(first));  // x86-64 is little endian
    } else {
      for (std::size_t k = 0; k < n * n_props; ++k)
        if (!(in >> values[k]))
          throw Error("ply", path, "truncated ASCII data at value " + std::to_string(first * n_props + k));
    }
    for (std::size_t i = 0; i < n; ++i) AppendVertex(l, &values[i * n_props], first + i, keep, path, &c);
    if (visit) {
      visit(c);
      c = GaussianCloud();
    }
  }
  return c;
}

GaussianCloud ReadPly(std::istream& in, std::size_t total_bytes, const GaussianFilter& keep, const std::string& path,
                      const GaussianChunkVisitor& visit = {}) {
  const PlyLayout layout = ReadHeader(in, path);
  const std::size_t header_bytes = static_cast<std::size_t>(in.tellg());
  return ReadBody(in, total_bytes - header_bytes, layout, keep, path, visit);
}

// The file opened and sized, or an Error naming it.
std::size_t OpenPly(const std::string& path, std::ifstream* in) {
  in->open(path, std::ios::binary);
  if (!*in) throw Error("ply", path, "cannot be opened");
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throw Error("ply", path, "cannot be sized: " + ec.message());
  return static_cast<std::size_t>(size);
}

}  // namespace

GaussianCloud ReadGaussiansPly(const std::string& path, const GaussianFilter& keep) {
  std::ifstream in;
  const std::size_t size = OpenPly(path, &in);
  return ReadPly(in, size, keep, path);
}

void ForEachGaussiansPlyChunk(const std::string& path, const GaussianChunkVisitor& visit) {
  std::ifstream in;
  const std::size_t size = OpenPly(path, &in);
  ReadPly(in, size, GaussianFilter(), path, visit);
}

GaussianCloud ParseGaussiansPly(const std::string& data, const std::string& path) {
  std::istringstream in(data);
  return ReadPly(in, data.size(), GaussianFilter(), path);
}

}  // namespace skyfall
