#include "splat/depth_prior.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <random>

#include "core/error.h"
#include "ingest/raster.h"

namespace skyfall {

SurfaceDepthPrior::SurfaceDepthPrior(const std::vector<Eigen::Vector3f>& points, double cell_m,
                                     const std::vector<float>& point_weights)
    : cell_(cell_m) {
  if (points.empty()) throw Error("depth_prior", "points", "no SfM points to fit a surface to");
  if (!(cell_m > 0)) throw Error("depth_prior", "cell_m", "must be > 0");
  if (!point_weights.empty() && point_weights.size() != points.size())
    throw Error("depth_prior", "point_weights", std::to_string(point_weights.size()) + " weights for " +
                                                    std::to_string(points.size()) + " points");
  Eigen::Vector3f lo = points[0], hi = points[0];
  for (const auto& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // The cells are centred on the points' lattice: points on a grid of this
  // spacing (the dense heights, one per cell centre) fall mid-cell, so their
  // float rounding cannot move one into a neighbour's cell, and HeightAt at a
  // point's position returns that point's height.
  x0_ = lo.x() - 0.5 * cell_m;
  y0_ = lo.y() - 0.5 * cell_m;
  nx_ = std::max(1, static_cast<int>(std::floor((hi.x() - x0_) / cell_m)) + 1);
  ny_ = std::max(1, static_cast<int>(std::floor((hi.y() - y0_) / cell_m)) + 1);
  std::vector<std::vector<float>> cells(static_cast<size_t>(nx_) * ny_);
  if (!point_weights.empty()) weight_.assign(cells.size(), 1.0f);
  for (std::size_t k = 0; k < points.size(); ++k) {
    const std::size_t cell = static_cast<std::size_t>(CellIndex(points[k].x(), points[k].y()));
    cells[cell].push_back(points[k].z());
    if (!weight_.empty()) weight_[cell] = std::min(weight_[cell], std::clamp(point_weights[k], 0.0f, 1.0f));
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  height_.assign(cells.size(), nan);
  for (size_t k = 0; k < cells.size(); ++k) {
    auto& c = cells[k];
    if (c.empty()) {
      if (!weight_.empty()) weight_[k] = 0.0f;  // filled from neighbours below: nothing measured
      continue;
    }
    std::nth_element(c.begin(), c.begin() + c.size() / 2, c.end());
    height_[k] = c[c.size() / 2];
  }
  // Fill holes from known neighbours, ring by ring.
  for (int pass = 0; pass < nx_ + ny_; ++pass) {
    std::vector<float> next = height_;
    bool missing = false;
    for (int j = 0; j < ny_; ++j)
      for (int i = 0; i < nx_; ++i) {
        if (std::isfinite(height_[static_cast<size_t>(j) * nx_ + i])) continue;
        double sum = 0;
        int n = 0;
        for (int dj = -1; dj <= 1; ++dj)
          for (int di = -1; di <= 1; ++di) {
            const int a = i + di, b = j + dj;
            if (a < 0 || b < 0 || a >= nx_ || b >= ny_) continue;
            const float v = height_[static_cast<size_t>(b) * nx_ + a];
            if (std::isfinite(v)) {
              sum += v;
              ++n;
            }
          }
        if (n) next[static_cast<size_t>(j) * nx_ + i] = static_cast<float>(sum / n);
        else missing = true;
      }
    height_ = std::move(next);
    if (!missing) break;
  }
  min_z_ = *std::min_element(height_.begin(), height_.end());
  max_z_ = *std::max_element(height_.begin(), height_.end());
  BuildBlockMaxima();
}

std::ptrdiff_t SurfaceDepthPrior::CellIndex(double x, double y) const {
  const int i = static_cast<int>(std::floor((x - x0_) / cell_)), j = static_cast<int>(std::floor((y - y0_) / cell_));
  if (i < 0 || j < 0 || i >= nx_ || j >= ny_) return -1;
  return static_cast<std::ptrdiff_t>(j) * nx_ + i;
}

float SurfaceDepthPrior::WeightAt(double x, double y) const {
  const std::ptrdiff_t k = CellIndex(x, y);
  if (k < 0) return 0.0f;
  return weight_.empty() ? 1.0f : weight_[static_cast<std::size_t>(k)];
}

double SurfaceDepthPrior::HeightAt(double x, double y) const {
  const std::ptrdiff_t k = CellIndex(x, y);
  if (k < 0) return std::numeric_limits<double>::quiet_NaN();
  return height_[static_cast<std::size_t>(k)];
}

DepthMap SurfaceDepthPrior::Estimate(const PinholeCamera& cam, const std::vector<float>&) {
  return DepthRelativeTo(cam, 0.0);
}

namespace {

// Casts every pixel's ray (camera centre c, direction d with unit camera z,
// so the ray parameter is the camera depth) and stores `hit(c, d)` (a depth,
// or NaN for no surface) less the reference depth; with `weights`, also the
// confidence of each hit (DepthMap::weight).
template <class Hit>
DepthMap CastRays(const PinholeCamera& cam, double reference_depth_m, Hit hit, const SurfaceDepthPrior* weights) {
  const int W = cam.width_px, H = cam.height_px;
  DepthMap out;
  out.depth.assign(static_cast<size_t>(W) * H, 0.0f);
  out.valid.assign(out.depth.size(), 0);
  if (weights) out.weight.assign(out.depth.size(), 0.0f);
  const Eigen::Vector3d c = cam.Centre();
  const Eigen::Matrix3d Rt = cam.cam_from_world_rotation.transpose();
  tbb::parallel_for(tbb::blocked_range<int>(0, H), [&](const tbb::blocked_range<int>& rows) {
    for (int r = rows.begin(); r < rows.end(); ++r)
      for (int col = 0; col < W; ++col) {
        const double yn = (r - cam.cy) / cam.fy;
        const Eigen::Vector3d d = Rt * Eigen::Vector3d((col - cam.cx - cam.skew * yn) / cam.fx, yn, 1.0);
        const double t = hit(c, d);
        if (!std::isfinite(t)) continue;
        out.depth[static_cast<size_t>(r) * W + col] = static_cast<float>(t - reference_depth_m);
        out.valid[static_cast<size_t>(r) * W + col] = 1;
        if (weights) {
          const Eigen::Vector3d at = c + t * d;
          out.weight[static_cast<size_t>(r) * W + col] = weights->WeightAt(at.x(), at.y());
        }
      }
  });
  return out;
}

constexpr double kNoHit = std::numeric_limits<double>::quiet_NaN();

}  // namespace

DepthMap SurfaceDepthPrior::NadirDepthRelativeTo(const PinholeCamera& cam, double reference_depth_m) const {
  return CastRays(cam, reference_depth_m, [&](const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
    if (d.z() >= -0.9) return kNoHit;  // not a downward view
    // Where the ray meets height h: t = (c.z - h) / -d.z; its ground point
    // moves by the ray's tiny tilt times the height change, so a few
    // fixed-point steps settle it.
    double t = (c.z() - max_z_) / -d.z();
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3d p = c + t * d;
      const double h = HeightAt(p.x(), p.y());
      if (!std::isfinite(h)) return kNoHit;
      t = (c.z() - h) / -d.z();
    }
    return t;
  }, weight_.empty() ? nullptr : this);
}

DepthMap SurfaceDepthPrior::DepthRelativeTo(const PinholeCamera& cam, double reference_depth_m) const {
  return CastRays(cam, reference_depth_m, [&](const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
    return FirstHit(c, d);
  }, weight_.empty() ? nullptr : this);
}

namespace {

// A grid of square cells over the xy plane: the cells the ray c + t d
// crosses for t in [t_in, t_out), in order (a 2-D DDA). `visit(i, j,
// t_enter, t_exit)` returns a depth to stop at, or NaN to go on. The first
// cell is taken from the ray's position at t_in, clamped to [first, last]
// (per axis), so a walk started on a cell boundary stays in the intended
// cell despite rounding. Every cell on the path is visited, however thin the
// ray's path through its corner.
struct CellGrid {
  double x0, y0, cell;
  int nx, ny;
};

template <class Visit>
double WalkCells(const CellGrid& g, const Eigen::Vector3d& c, const Eigen::Vector3d& d, double t_in, double t_out,
                 const int first[2], const int last[2], Visit visit) {
  const double lo[2] = {g.x0, g.y0};
  const Eigen::Vector3d start = c + t_in * d;
  int cell[2], step[2];
  double t_next[2], t_delta[2];
  for (int a = 0; a < 2; ++a) {
    cell[a] = std::clamp(static_cast<int>(std::floor((start[a] - lo[a]) / g.cell)), first[a], last[a]);
    if (d[a] > 0) {
      step[a] = 1;
      t_next[a] = (lo[a] + (cell[a] + 1) * g.cell - c[a]) / d[a];
      t_delta[a] = g.cell / d[a];
    } else if (d[a] < 0) {
      step[a] = -1;
      t_next[a] = (lo[a] + cell[a] * g.cell - c[a]) / d[a];
      t_delta[a] = -g.cell / d[a];
    } else {
      step[a] = 0;
      t_next[a] = t_delta[a] = std::numeric_limits<double>::infinity();
    }
  }
  for (double t_enter = t_in; t_enter < t_out;) {
    const double t_exit = std::min({t_next[0], t_next[1], t_out});
    const double hit = visit(cell[0], cell[1], t_enter, t_exit);
    if (!std::isnan(hit)) return hit;
    const int a = t_next[0] < t_next[1] ? 0 : 1;
    cell[a] += step[a];
    if (cell[a] < first[a] || cell[a] > last[a]) return kNoHit;
    t_enter = t_exit;
    t_next[a] += t_delta[a];
  }
  return kNoHit;
}

}  // namespace

void SurfaceDepthPrior::BuildBlockMaxima() {
  bx_ = (nx_ + kBlockCells - 1) / kBlockCells;
  by_ = (ny_ + kBlockCells - 1) / kBlockCells;
  block_max_.assign(static_cast<std::size_t>(bx_) * by_, -std::numeric_limits<float>::infinity());
  for (int j = 0; j < ny_; ++j)
    for (int i = 0; i < nx_; ++i) {
      float& m = block_max_[static_cast<std::size_t>(j / kBlockCells) * bx_ + i / kBlockCells];
      m = std::max(m, height_[static_cast<std::size_t>(j) * nx_ + i]);
    }
}

double SurfaceDepthPrior::FirstHit(const Eigen::Vector3d& c, const Eigen::Vector3d& d) const {
  if (d.z() >= 0) return kNoHit;  // looking up: no surface
  // The part of the ray within the surface's height range and over its grid.
  double t_in = std::max(0.0, (max_z_ + 1.0 - c.z()) / d.z());
  double t_out = (min_z_ - 1.0 - c.z()) / d.z();
  const double lo[2] = {x0_, y0_}, hi[2] = {x0_ + nx_ * cell_, y0_ + ny_ * cell_};
  for (int a = 0; a < 2; ++a) {
    if (d[a] == 0.0) {
      if (c[a] < lo[a] || c[a] >= hi[a]) return kNoHit;
      continue;
    }
    const double t0 = (lo[a] - c[a]) / d[a], t1 = (hi[a] - c[a]) / d[a];
    t_in = std::max(t_in, std::min(t0, t1));
    t_out = std::min(t_out, std::max(t0, t1));
  }
  if (!(t_in < t_out)) return kNoHit;
  // Blocks of cells first: the ray descends, so it stays above a block whose
  // highest cell is below it where it leaves the block; only the other blocks
  // are walked cell by cell. The surface is constant over a cell, so the ray
  // meets it in a cell either where it enters (a wall) or where it descends
  // through the cell's height (a roof).
  const CellGrid blocks{x0_, y0_, kBlockCells * cell_, bx_, by_}, cells{x0_, y0_, cell_, nx_, ny_};
  const int first_block[2] = {0, 0}, last_block[2] = {bx_ - 1, by_ - 1};
  return WalkCells(blocks, c, d, t_in, t_out, first_block, last_block, [&](int bi, int bj, double tb0, double tb1) {
    if (c.z() + tb1 * d.z() > block_max_[static_cast<std::size_t>(bj) * bx_ + bi]) return kNoHit;
    const int first[2] = {bi * kBlockCells, bj * kBlockCells};
    const int last[2] = {std::min(nx_, (bi + 1) * kBlockCells) - 1, std::min(ny_, (bj + 1) * kBlockCells) - 1};
    return WalkCells(cells, c, d, tb0, tb1, first, last, [&](int i, int j, double t0, double t1) {
      const double h = height_[static_cast<std::size_t>(j) * nx_ + i];
      if (c.z() + t0 * d.z() <= h) return t0;                   // meets the cell's wall
      if (c.z() + t1 * d.z() <= h) return (h - c.z()) / d.z();  // meets its top
      return kNoHit;
    });
  });
}

CommandDepthPrior::CommandDepthPrior(std::string command, std::string work_dir)
    : command_(std::move(command)), work_dir_(std::move(work_dir)) {
  if (command_.find("{in}") == std::string::npos || command_.find("{out}") == std::string::npos) {
    throw Error("depth_prior", "command", "must contain {in} and {out}: '" + command_ + "'");
  }
}

DepthMap CommandDepthPrior::Estimate(const PinholeCamera& cam, const std::vector<float>& rgb) {
  namespace fs = std::filesystem;
  const int W = cam.width_px, H = cam.height_px;
  const std::string in = (fs::path(work_dir_) / ("pseudo_" + std::to_string(calls_) + ".png")).string();
  const std::string out = (fs::path(work_dir_) / ("pseudo_" + std::to_string(calls_) + "_depth.tif")).string();
  ++calls_;
  WriteUnitPng(in, W, H, 3, rgb);
  std::string cmd = command_;
  cmd.replace(cmd.find("{in}"), 4, "'" + in + "'");
  cmd.replace(cmd.find("{out}"), 5, "'" + out + "'");
  if (std::system(cmd.c_str()) != 0) throw Error("depth_prior", command_, "failed on " + in);
  const FloatBand band = ReadFloatBand(out);
  if (band.width_px != W || band.height_px != H) {
    throw Error("depth_prior", out, "is " + std::to_string(band.width_px) + "x" + std::to_string(band.height_px) +
                                        ", the view is " + std::to_string(W) + "x" + std::to_string(H));
  }
  DepthMap m;
  m.depth = band.values;
  m.valid.resize(m.depth.size());
  for (size_t k = 0; k < m.depth.size(); ++k) m.valid[k] = std::isfinite(m.depth[k]) ? 1 : 0;
  std::error_code ec;
  fs::remove(in, ec);
  fs::remove(out, ec);
  return m;
}

PinholeCamera NadirCamera(const Eigen::Vector3d& look_at, double gsd_m, int size_px, double height_m) {
  PinholeCamera cam;
  cam.cam_from_world_rotation << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  const Eigen::Vector3d eye = look_at + Eigen::Vector3d(0, 0, height_m);
  cam.cam_from_world_translation = -cam.cam_from_world_rotation * eye;
  cam.fx = cam.fy = height_m / gsd_m;
  cam.cx = cam.cy = 0.5 * (size_px - 1);
  cam.width_px = cam.height_px = size_px;
  return cam;
}

PinholeCamera SamplePseudoCamera(const PseudoCameraOptions& o, const Eigen::Vector3d& centre, std::uint64_t sample) {
  std::mt19937_64 rng(0x5EED0000ull + sample);
  std::normal_distribution<double> n(0.0, o.look_at_sigma_m);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Eigen::Vector3d target = centre + Eigen::Vector3d(n(rng), n(rng), 0.0);
  const double az = 2 * M_PI * u(rng);
  const double el = (o.min_elevation_deg + (o.max_elevation_deg - o.min_elevation_deg) * u(rng)) * M_PI / 180.0;
  const Eigen::Vector3d eye =
      target + o.radius_m * Eigen::Vector3d(std::cos(el) * std::sin(az), std::cos(el) * std::cos(az), std::sin(el));
  return LookAtCamera(eye, target, o.fov_deg, o.size_px, o.size_px);
}

}  // namespace skyfall
