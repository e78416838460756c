#include "merge/lod.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <numeric>
#include <set>
#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/gaussian_moments.h"
#include "splat/gaussian_spill.h"
#include "splat/ply.h"

namespace skyfall {

namespace fs = std::filesystem;

namespace {

// Opacity cap of a merged Gaussian (its logit must stay finite); when the
// merged mass asks for more the Gaussian is saturated and mass is lost.
constexpr double kMaxOpacity = 0.99;
constexpr double kMinOpacity = 1e-6;
// [m] smallest standard deviation of a merged Gaussian (a flat merged sheet
// keeps a finite, tiny thickness).
constexpr double kMinSigmaM = 1e-4;

double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

}  // namespace

void LodOptions::Check() const { CheckOptionRanges(*this, "lod"); }

double GaussianMass(const GaussianCloud& cloud, std::size_t i) {
  return Sigmoid(cloud.opacity_logits[i]) * std::exp(static_cast<double>(cloud.log_scales[i].sum()));
}

bool MergeGaussians(const GaussianCloud& cloud, const std::vector<std::size_t>& members, GaussianCloud* out) {
  if (members.size() == 1) {
    out->Append(cloud, members[0]);
    return true;
  }
  const GaussianMoments m = WeightedMoments(cloud, members, [&](std::size_t i) { return GaussianMass(cloud, i); });
  Eigen::Quaterniond rotation;
  Eigen::Vector3d sigma;
  CovarianceAxes(m.covariance, kMinSigmaM, &rotation, &sigma);
  const double wanted_opacity = m.weight / sigma.prod();
  AppendGaussian(m, rotation, sigma, std::clamp(wanted_opacity, kMinOpacity, kMaxOpacity), out);
  return wanted_opacity <= kMaxOpacity;
}

namespace {

using VoxelKey = std::array<std::int64_t, 3>;
using BlockKey = std::array<std::int64_t, 2>;

// Floor of x / edge in double; with edges that are one base size times
// powers of two, voxels nest in coarser voxels and in blocks exactly
// (scaling by a power of two commutes with rounding).
std::int64_t Cell(double x, double edge_m) { return static_cast<std::int64_t>(std::floor(x / edge_m)); }
VoxelKey VoxelOf(const Eigen::Vector3f& p, double voxel_m) {
  return {Cell(p.x(), voxel_m), Cell(p.y(), voxel_m), Cell(p.z(), voxel_m)};
}
BlockKey BlockOf(const Eigen::Vector3f& p, double block_m) { return {Cell(p.x(), block_m), Cell(p.y(), block_m)}; }
std::string BlockName(const BlockKey& b) { return std::to_string(b[0]) + "_" + std::to_string(b[1]); }
std::int64_t FloorDiv(std::int64_t a, std::int64_t b) { return a / b - ((a % b != 0) && ((a < 0) != (b < 0))); }

struct Bounds {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
  void Add(const Eigen::Vector3f& p) {
    lo = lo.cwiseMin(p.cast<double>());
    hi = hi.cwiseMax(p.cast<double>());
  }
  void To(LodLevel* l) const {
    l->min_m = l->count ? lo : Eigen::Vector3d::Zero();
    l->max_m = l->count ? hi : Eigen::Vector3d::Zero();
  }
};

// A finest Gaussian's centre and the centre of its current stand-in.
struct RepRecord {
  std::array<float, 3> finest, rep;
};
Eigen::Vector3f Vec(const std::array<float, 3>& a) { return {a[0], a[1], a[2]}; }

// A level's Gaussians on disk, by the block of the `block_m` grid their
// centre lies in, each tagged with its index in the level's file; and the
// finest Gaussians' records, by the block of their stand-in's centre in
// that level (which is the block of a Gaussian of it).
struct LevelSpill {
  LevelSpill(const fs::path& dir, std::size_t budget_bytes)
      : gaussians(dir / "g", kSpilledGaussianBytes, budget_bytes / 2),
        reps(dir / "r", sizeof(RepRecord), budget_bytes / 2) {}
  void AddGaussian(const GaussianCloud& cloud, std::size_t i, std::uint64_t index, double block_m) {
    const BlockKey b = BlockOf(cloud.means[i], block_m);
    blocks.insert(b);
    SpillGaussian(gaussians, BlockName(b), cloud, i, index);
  }
  void AddRep(const RepRecord& r, double block_m) { reps.Add(BlockName(BlockOf(Vec(r.rep), block_m)), &r); }
  KeyedSpill gaussians, reps;
  std::set<BlockKey> blocks;
};

// The block's Gaussians of a level, gathered from the spill's blocks that
// make it up, in the level's file order.
GaussianCloud GatherBlock(LevelSpill& spill, const std::vector<BlockKey>& parts) {
  GaussianCloud gathered;
  std::vector<std::uint64_t> tags;
  for (const BlockKey& b : parts) {
    std::vector<std::uint64_t> part_tags;
    const GaussianCloud part = ReadSpilledGaussians(spill.gaussians, BlockName(b), &part_tags);
    for (std::size_t i = 0; i < part.size(); ++i) gathered.Append(part, i);
    tags.insert(tags.end(), part_tags.begin(), part_tags.end());
  }
  if (parts.size() == 1) return gathered;  // one block's file is in file order already
  std::vector<std::size_t> order(gathered.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return tags[a] < tags[b]; });
  GaussianCloud sorted;
  for (std::size_t i : order) sorted.Append(gathered, i);
  return sorted;
}

// `prev` merged by voxels of `voxel_m`, appended to `out`, grouped by
// sorted (voxel key, index): a deterministic order. `stand_in` maps each
// voxel to the merged Gaussian that stands for its members. Returns how
// many merged Gaussians saturated.
std::size_t MergeByVoxel(const GaussianCloud& prev, double voxel_m, GaussianCloud* out,
                         std::map<VoxelKey, std::size_t>* stand_in) {
  std::vector<std::pair<VoxelKey, std::size_t>> keyed(prev.size());
  for (std::size_t i = 0; i < prev.size(); ++i) keyed[i] = {VoxelOf(prev.means[i], voxel_m), i};
  std::sort(keyed.begin(), keyed.end());
  std::size_t saturated = 0;
  std::vector<std::size_t> members;
  for (std::size_t a = 0; a < keyed.size();) {
    std::size_t b = a;
    members.clear();
    while (b < keyed.size() && keyed[b].first == keyed[a].first) members.push_back(keyed[b++].second);
    (*stand_in)[keyed[a].first] = out->size();
    saturated += !MergeGaussians(prev, members, out);
    a = b;
  }
  return saturated;
}

// A level built (maybe only tried): its figures, its file (not yet
// committed) and its spill, the next level's input.
struct LevelTry {
  LodLevel level;
  std::unique_ptr<GaussiansPlyWriter> file;
  std::unique_ptr<LevelSpill> spill;
};

// Level `k` from `prev` with voxels of `voxel_m`, block by block.
LevelTry BuildLevel(int k, double voxel_m, double base_block_m, LevelSpill& prev, const fs::path& spill_dir,
                    std::size_t budget_bytes, const fs::path& file) {
  LevelTry t;
  t.level.level = k;
  t.level.voxel_m = voxel_m;
  t.file = std::make_unique<GaussiansPlyWriter>(file.string());
  t.spill = std::make_unique<LevelSpill>(spill_dir, budget_bytes);
  // Blocks of the larger of the base block and the voxel: whole voxels.
  const auto ratio = static_cast<std::int64_t>(std::llround(std::max(base_block_m, voxel_m) / base_block_m));
  std::map<BlockKey, std::vector<BlockKey>> blocks;
  for (const BlockKey& b : prev.blocks) blocks[{FloorDiv(b[0], ratio), FloorDiv(b[1], ratio)}].push_back(b);
  Bounds bounds;
  for (const auto& [block, parts] : blocks) {
    const GaussianCloud members = GatherBlock(prev, parts);
    GaussianCloud merged;
    std::map<VoxelKey, std::size_t> stand_in;
    t.level.saturated += MergeByVoxel(members, voxel_m, &merged, &stand_in);
    for (std::size_t j = 0; j < merged.size(); ++j) {
      t.file->Add(merged, j);
      t.spill->AddGaussian(merged, j, t.level.count++, base_block_m);
      bounds.Add(merged.means[j]);
    }
    // The finest Gaussians whose stand-ins were merged here: their new
    // stand-in is the Gaussian of the voxel the old one's centre is in.
    for (const BlockKey& b : parts) {
      const std::string bytes = prev.reps.Read(BlockName(b));
      for (std::size_t r = 0; r < bytes.size() / sizeof(RepRecord); ++r) {
        RepRecord rec;
        std::memcpy(&rec, bytes.data() + r * sizeof(RepRecord), sizeof(rec));
        const auto it = stand_in.find(VoxelOf(Vec(rec.rep), voxel_m));
        if (it == stand_in.end()) throw Error("lod", "level " + std::to_string(k), "a stand-in lost its block");
        const Eigen::Vector3f& centre = merged.means[it->second];
        t.level.geometric_error_m = std::max(t.level.geometric_error_m, (Vec(rec.finest) - centre).cast<double>().norm());
        rec.rep = {centre.x(), centre.y(), centre.z()};
        t.spill->AddRep(rec, base_block_m);
      }
    }
  }
  bounds.To(&t.level);
  return t;
}

// The base block: block_m raised to base_voxel_m times a power of two.
double BaseBlockM(const LodOptions& o) {
  double b = o.base_voxel_m;
  while (b < o.block_m) b *= 2;
  return b;
}

std::string LodFileName(int level) { return "lod_" + std::to_string(level) + ".ply"; }

void WriteLodIndex(const fs::path& dir, const std::vector<LodLevel>& levels) {
  nlohmann::json list = nlohmann::json::array();
  for (const LodLevel& l : levels) {
    list.push_back({{"level", l.level},
                    {"file", LodFileName(l.level)},
                    {"voxel_m", l.voxel_m},
                    {"geometric_error_m", l.geometric_error_m},
                    {"count", l.count},
                    {"saturated", l.saturated},
                    {"bounds_min_m", {l.min_m.x(), l.min_m.y(), l.min_m.z()}},
                    {"bounds_max_m", {l.max_m.x(), l.max_m.y(), l.max_m.z()}}});
  }
  const nlohmann::json doc = {{"schema", "skyfall.lod/1"},
                              {"frame", "city ENU (see the scene's frame.json)"},
                              {"levels", list}};
  WriteFileAtomic((dir / "lod.json").string(), doc.dump(2) + "\n");
}

}  // namespace

std::vector<LodLevel> WriteLodLevels(const LodOptions& options, const GaussianChunks& finest, const std::string& dir) {
  options.Check();
  const fs::path out(dir);
  const fs::path spill_root = out / ".lod_spill";
  const double base_block_m = BaseBlockM(options);
  const auto budget = static_cast<std::size_t>(options.spill_buffer_mb * 1e6);
  std::vector<LodLevel> levels;
  // A merge killed while it built the pyramid leaves its spill behind: a
  // fresh build starts from an empty one.
  fs::remove_all(spill_root);
  // Level 0: written as given; each finest Gaussian is its own stand-in.
  int spills = 0;
  auto prev = std::make_unique<LevelSpill>(spill_root / std::to_string(spills++), budget);
  {
    LodLevel base;
    Bounds bounds;
    GaussiansPlyWriter file((out / LodFileName(0)).string());
    finest([&](const GaussianCloud& chunk) {
      for (std::size_t i = 0; i < chunk.size(); ++i) {
        file.Add(chunk, i);
        bounds.Add(chunk.means[i]);
        prev->AddGaussian(chunk, i, base.count++, base_block_m);
        const Eigen::Vector3f& p = chunk.means[i];
        prev->AddRep({{p.x(), p.y(), p.z()}, {p.x(), p.y(), p.z()}}, base_block_m);
      }
    });
    file.Finish();
    bounds.To(&base);
    levels.push_back(base);
  }
  const double extent_m = (levels[0].max_m - levels[0].min_m).norm();
  double voxel_m = options.base_voxel_m;
  for (int k = 1; k <= options.max_levels; voxel_m *= 2) {
    const std::size_t prev_count = levels.back().count;
    if (prev_count <= options.min_gaussians || voxel_m > 2 * extent_m + options.base_voxel_m) break;
    LevelTry t = BuildLevel(k, voxel_m, base_block_m, *prev, spill_root / std::to_string(spills++), budget,
                            out / LodFileName(k));
    // Too little simplification at this voxel size: try the next one (the
    // try's file and spill are dropped).
    if (static_cast<double>(t.level.count) > options.min_reduction * prev_count) continue;
    t.file->Finish();
    levels.push_back(t.level);
    prev = std::move(t.spill);
    ++k;
  }
  prev.reset();
  fs::remove_all(spill_root);
  WriteLodIndex(out, levels);
  return levels;
}

}  // namespace skyfall
