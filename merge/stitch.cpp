#include "merge/stitch.h"

#include <openvdb/openvdb.h>

#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <mutex>
#include <string>

#include "core/error.h"
#include "ingest/geo.h"

namespace skyfall {
namespace {

void InitOpenVdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

openvdb::MaskGrid::Ptr NewMask(double voxel_m) {
  openvdb::MaskGrid::Ptr grid = openvdb::MaskGrid::create();
  grid->setTransform(openvdb::math::Transform::createLinearTransform(voxel_m));
  return grid;
}

// The occupancy cell of a point: its voxel, or its ground column (z = 0).
openvdb::Coord VoxelOf(const openvdb::MaskGrid& grid, const Eigen::Vector3f& p, bool columns) {
  return grid.transform().worldToIndexCellCentered(openvdb::Vec3d(p.x(), p.y(), columns ? 0.0 : p.z()));
}

bool AnyActiveNear(const openvdb::MaskGrid::ConstAccessor& acc, const openvdb::Coord& c, int radius) {
  for (int dz = -radius; dz <= radius; ++dz)
    for (int dy = -radius; dy <= radius; ++dy)
      for (int dx = -radius; dx <= radius; ++dx)
        if (acc.isValueOn(c.offsetBy(dx, dy, dz))) return true;
  return false;
}

}  // namespace

void StitchOptions::Check() const { CheckOptionRanges(*this, "merge"); }

Eigen::Isometry3d FrameChange(const GeodeticPoint& from_origin, const GeodeticPoint& to_origin) {
  if (from_origin.lon_deg == to_origin.lon_deg && from_origin.lat_deg == to_origin.lat_deg &&
      from_origin.height_m == to_origin.height_m) {
    return Eigen::Isometry3d::Identity();
  }
  // Both frames are ECEF rotated and shifted, so the map between them is
  // rigid; three points through the geodetic round trip define it.
  const EnuFrame from(from_origin), to(to_origin);
  auto map = [&](const Eigen::Vector3d& p) { return to.EnuFromGeodetic(from.GeodeticFromEnu(p)); };
  const Eigen::Vector3d t = map(Eigen::Vector3d::Zero());
  constexpr double kArmM = 1000.0;
  Eigen::Matrix3d r;
  for (int k = 0; k < 3; ++k) r.col(k) = (map(kArmM * Eigen::Vector3d::Unit(k)) - t) / kArmM;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = svd.matrixU() * svd.matrixV().transpose();  // nearest rotation
  out.translation() = t;
  return out;
}

GaussianCloud TransformCloud(const GaussianCloud& cloud, const Eigen::Isometry3d& to_from) {
  if (to_from.isApprox(Eigen::Isometry3d::Identity(), 0.0)) return cloud;
  GaussianCloud out = cloud;
  const Eigen::Matrix3d r = to_from.linear();
  const Eigen::Quaterniond qr(r);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    out.means[i] = (to_from * cloud.means[i].cast<double>()).cast<float>();
    const Eigen::Vector4f& q = cloud.rotations[i];
    const Eigen::Quaterniond rotated = qr * Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
    out.rotations[i] = Eigen::Vector4f(rotated.w(), rotated.x(), rotated.y(), rotated.z());
    // Degree-1 SH: the view-dependent term is v . dir with v = (-c_x, -c_y, c_z)
    // in the [dc, y, z, x] order, so v rotates like a vector.
    for (int c = 0; c < 3; ++c) {
      auto& sh = out.sh[i];
      const Eigen::Vector3d v = r * Eigen::Vector3d(-sh[c * 4 + 3], -sh[c * 4 + 1], sh[c * 4 + 2]);
      sh[c * 4 + 1] = static_cast<float>(-v.y());
      sh[c * 4 + 2] = static_cast<float>(v.z());
      sh[c * 4 + 3] = static_cast<float>(-v.x());
    }
  }
  return out;
}

namespace {

void CheckOneTiling(const std::vector<TileSpec>& tiles) {
  if (tiles.empty()) throw Error("merge", "", "no tile to merge");
  const TileGrid& grid = tiles[0].grid;
  for (const TileSpec& t : tiles) {
    if (t.grid.cols != grid.cols || t.grid.rows != grid.rows || t.grid.tile_m != grid.tile_m ||
        !t.grid.origin_m.isApprox(grid.origin_m, 1e-9)) {
      throw Error("merge", t.id, "comes from another tiling than " + tiles[0].id + " (grids differ)");
    }
  }
}

// Hands `use` tile k's Gaussians twice over: as the tile has them (its
// boxes and the ownership are in the frame it was planned in) and in the
// city frame. A tile planned in the city's frame (every tile of one tiling)
// is not copied.
using TwoFrameUser = std::function<void(const GaussianCloud& own, const GaussianCloud& city)>;
void VisitInBothFrames(const TileSource& tiles, std::size_t k, const GeodeticPoint& city_origin,
                       const TwoFrameUser& use) {
  const Eigen::Isometry3d to_city = FrameChange(tiles.specs[k].enu_origin, city_origin);
  tiles.visit(k, [&](const GaussianCloud& own) {
    if (to_city.isApprox(Eigen::Isometry3d::Identity(), 0.0)) {
      use(own, own);
    } else {
      use(own, TransformCloud(own, to_city));
    }
  });
}

bool OwnsIt(const TileOwnership& ownership, const TileSpec& spec, const Eigen::Vector3f& p) {
  const Eigen::Vector2i owner = ownership.Owner(p.x(), p.y());
  return owner.x() == spec.col && owner.y() == spec.row;
}

// First pass: every core Gaussian is kept; returns the occupancy of the
// opaque ones.
openvdb::MaskGrid::Ptr KeepCores(const StitchOptions& options, const GeodeticPoint& city_origin,
                                 const TileSource& tiles, const StitchSink& keep, StitchResult* result) {
  openvdb::MaskGrid::Ptr occupied = NewMask(options.voxel_m);
  for (std::size_t k = 0; k < tiles.size(); ++k) {
    VisitInBothFrames(tiles, k, city_origin, [&](const GaussianCloud& own, const GaussianCloud& city) {
      openvdb::MaskGrid::Ptr mine = NewMask(options.voxel_m);
      auto acc = mine->getAccessor();
      for (std::size_t i = 0; i < own.size(); ++i) {
        if (!OwnsIt(result->ownership, tiles.specs[k], own.means[i])) continue;
        if (OpacityOfLogit(city.opacity_logits[i]) >= options.min_opacity) {
          acc.setValueOn(VoxelOf(*mine, city.means[i], options.occupancy_columns));
        }
        keep(k, city, i);
        ++result->kept_in_core;
      }
      result->occupied_voxels_per_tile.push_back(mine->activeVoxelCount());
      occupied->topologyUnion(*mine);
    });
  }
  return occupied;
}

// Second pass, over the overlap bands: duplicates of the owners' geometry
// go; Gaussians where no core has geometry fill the hole, once (fills of
// earlier tiles count as occupied for later ones).
void FillFromOverlaps(const StitchOptions& options, const GeodeticPoint& city_origin, const TileSource& tiles,
                      const openvdb::MaskGrid& occupied, const StitchSink& keep, StitchResult* result) {
  openvdb::MaskGrid::Ptr filled = NewMask(options.voxel_m);
  for (std::size_t k = 0; k < tiles.size(); ++k) {
    const TileSpec& spec = tiles.specs[k];
    VisitInBothFrames(tiles, k, city_origin, [&](const GaussianCloud& own, const GaussianCloud& city) {
      const auto occupied_acc = occupied.getConstAccessor();
      const auto filled_acc = filled->getConstAccessor();
      std::vector<std::size_t> fills;
      for (std::size_t i = 0; i < own.size(); ++i) {
        const Eigen::Vector3f& p = own.means[i];
        if (OwnsIt(result->ownership, spec, p)) continue;
        if (!spec.extent.Contains(p.x(), p.y())) {
          ++result->outside_extent;
        } else if (OpacityOfLogit(own.opacity_logits[i]) < options.min_opacity) {
          ++result->transparent_dropped;
        } else {
          const openvdb::Coord c = VoxelOf(occupied, city.means[i], options.occupancy_columns);
          if (AnyActiveNear(occupied_acc, c, options.match_radius_voxels) ||
              AnyActiveNear(filled_acc, c, options.match_radius_voxels)) {
            ++result->duplicates_removed;
          } else {
            fills.push_back(i);
          }
        }
      }
      auto fill_acc = filled->getAccessor();
      for (std::size_t i : fills) {
        fill_acc.setValueOn(VoxelOf(*filled, city.means[i], options.occupancy_columns));
        keep(k, city, i);
      }
      result->holes_filled += fills.size();
    });
  }
}

std::map<std::string, double> StitchMetrics(const StitchResult& r) {
  return {{"gaussians", static_cast<double>(r.kept_in_core + r.holes_filled)},
          {"kept_in_core", static_cast<double>(r.kept_in_core)},
          {"duplicates_removed", static_cast<double>(r.duplicates_removed)},
          {"holes_filled", static_cast<double>(r.holes_filled)},
          {"outside_extent_dropped", static_cast<double>(r.outside_extent)},
          {"transparent_overlap_dropped", static_cast<double>(r.transparent_dropped)},
          {"occupied_voxels_union", static_cast<double>(r.occupied_voxels_union)},
          {"seam_lines", static_cast<double>(r.ownership.lines())},
          {"seam_line_mean_offset_m", r.ownership.MeanDeviationM()}};
}

}  // namespace

StitchResult StitchTiles(const StitchOptions& options, const GeodeticPoint& city_origin, const TileSource& tiles,
                         const TileOwnership& ownership, const StitchSink& keep) {
  options.Check();
  InitOpenVdb();
  Stopwatch clock;
  CheckOneTiling(tiles.specs);
  StitchResult result;
  result.report.stage = "merge";
  result.ownership = ownership;
  const openvdb::MaskGrid::Ptr occupied = KeepCores(options, city_origin, tiles, keep, &result);
  FillFromOverlaps(options, city_origin, tiles, *occupied, keep, &result);
  result.occupied_voxels_union = occupied->activeVoxelCount();
  result.report.metrics = StitchMetrics(result);
  result.report.seconds = clock.Seconds();
  return result;
}

StitchResult StitchTiles(const StitchOptions& options, const GeodeticPoint& city_origin,
                         const std::vector<TileCloud>& tiles, const TileOwnership* ownership) {
  const TileSource source = TilesInMemory(tiles);
  if (tiles.empty()) CheckOneTiling(source.specs);
  GaussianCloud cloud;
  std::vector<int> source_tile;
  StitchResult result =
      StitchTiles(options, city_origin, source,
                  ownership ? *ownership : PlanSeamLinesOnCentres(options.seam_lines, source),
                  [&](std::size_t k, const GaussianCloud& from, std::size_t i) {
                    cloud.Append(from, i);
                    source_tile.push_back(static_cast<int>(k));
                  });
  result.cloud = std::move(cloud);
  result.source_tile = std::move(source_tile);
  return result;
}

}  // namespace skyfall
