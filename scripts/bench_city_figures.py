#!/usr/bin/python3
"""The figures of scripts/bench_city.sh from a finished city run.

  bench_city_figures.py jobs ROOT RUN              tile id, tile dir, AOI, EPSG: one line
                                                   per (tile, AOI its core overlaps)
  bench_city_figures.py figures KM N BLOCK_M ROOT RUN OUT JSON EXECUTOR
                                                   prints and writes OUT/JSON

Frames: error maps are UTM rasters (row 0 the north edge, pixel centres at
(col + 0.5, row + 0.5) x GSD from the upper-left corner); tile cores are boxes in
the city's local ENU frame (east, north in metres from tiles.json's enu_origin).
Pixel centres go UTM -> WGS84 geodetic (GDAL/PROJ) -> ENU (WGS84 ellipsoid,
at the origin's ellipsoidal height: a horizontal position, so the height used
moves it by far less than a millimetre over a few km).
"""
import functools
import glob
import json
import math
import os
import sys

import numpy as np
from osgeo import gdal, osr

gdal.UseExceptions()
BORDER_BAND_M = 10.0  # cells this close to an interior tile border count as "border" (the 10 m)
# error_seams: pairs of adjacent cells whose truth steps less than this are smooth (a kerb,
# a roof's slope over 0.5 m); walls are left out.
SMOOTH_TRUTH_STEP_M = 1.0
WGS84_A, WGS84_F = 6378137.0, 1 / 298.257223563
WGS84_E2 = WGS84_F * (2 - WGS84_F)


def ecef(lon_deg, lat_deg, h_m):
    lon, lat = np.radians(lon_deg), np.radians(lat_deg)
    n = WGS84_A / np.sqrt(1 - WGS84_E2 * np.sin(lat) ** 2)
    return np.stack([(n + h_m) * np.cos(lat) * np.cos(lon), (n + h_m) * np.cos(lat) * np.sin(lon),
                     (n * (1 - WGS84_E2) + h_m) * np.sin(lat)], axis=-1)


def enu_of_geodetic(origin, lon_deg, lat_deg):
    """East, north [m] of geodetic points in the ENU frame at `origin` (lon, lat, h)."""
    lon0, lat0, h0 = origin
    d = ecef(lon_deg, lat_deg, np.full_like(lon_deg, h0)) - ecef(np.array(lon0), np.array(lat0), np.array(h0))
    lo, la = math.radians(lon0), math.radians(lat0)
    east = -math.sin(lo) * d[..., 0] + math.cos(lo) * d[..., 1]
    north = -math.sin(la) * math.cos(lo) * d[..., 0] - math.sin(la) * math.sin(lo) * d[..., 1] + math.cos(la) * d[..., 2]
    return east, north


def utm_to_geodetic(epsg):
    src, dst = osr.SpatialReference(), osr.SpatialReference()
    src.ImportFromEPSG(epsg)
    dst.ImportFromEPSG(4326)
    dst.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)  # (lon, lat)
    return osr.CoordinateTransformation(src, dst)


@functools.lru_cache(maxsize=None)
def grid_enu(geotransform, rows, cols, origin, epsg):
    """ENU (east, north) of every pixel centre of a UTM grid. A tile's own
    error maps lie on its AOIs' truth grids: each grid is converted once."""
    x0, dx, _, y0, _, dy = geotransform
    cc, rr = np.meshgrid(np.arange(cols) + 0.5, np.arange(rows) + 0.5)
    e, n = x0 + cc * dx, y0 + rr * dy
    lonlat = np.array(utm_to_geodetic(epsg).TransformPoints(np.stack([e.ravel(), n.ravel()], axis=1)))
    east, north = enu_of_geodetic(origin, lonlat[:, 0], lonlat[:, 1])
    return east.reshape(rows, cols), north.reshape(rows, cols)


def raster_enu(path, origin, epsg):
    """The raster's band 1 and the ENU (east, north) of every pixel centre."""
    ds = gdal.Open(path)
    values = ds.GetRasterBand(1).ReadAsArray().astype(np.float64)
    east, north = grid_enu(tuple(ds.GetGeoTransform()), *values.shape, tuple(origin), epsg)
    return values, east, north


def city_dirs(run):
    return [os.path.dirname(os.path.dirname(p)) for p in sorted(glob.glob(os.path.join(run, "*", "tiles", "tiles.json")))]


def tiles_of(city_dir):
    index = json.load(open(os.path.join(city_dir, "tiles", "tiles.json")))
    specs = []
    for t in index["tiles"]:
        d = os.path.join(city_dir, "tiles", t["id"])
        if os.path.exists(os.path.join(d, "tile.json")):
            specs.append((d, json.load(open(os.path.join(d, "tile.json")))))
    o = index["enu_origin"]
    return index, (o["lon_deg"], o["lat_deg"], o["height_m"]), specs


def in_core(spec, east, north):
    c = spec["core"]
    return (east >= c["min_east_m"]) & (east < c["max_east_m"]) & (north >= c["min_north_m"]) & (north < c["max_north_m"])


def border_distance(grid, east, north):
    """Distance [m] to the nearest interior tile border (inf for a grid of one tile)."""
    dist = np.full(east.shape, np.inf)
    ox, oy, side = grid["origin_east_m"], grid["origin_north_m"], grid["tile_m"]
    for k in range(1, grid["cols"]):
        dist = np.minimum(dist, np.abs(east - (ox + k * side)))
    for k in range(1, grid["rows"]):
        dist = np.minimum(dist, np.abs(north - (oy + k * side)))
    return dist


def epsg_of(tile_dir):
    return json.load(open(os.path.join(tile_dir, "aoi.json")))["utm"]["epsg"]


def truth_box_enu(root, aoi, origin, epsg):
    """ENU bounding box (min_e, min_n, max_e, max_n) of an AOI's truth grid
    (_DSM.txt: lower-left easting, northing, size [px], GSD [m])."""
    e0, n0, size, gsd = [float(v) for v in open(os.path.join(root, "Track3-Truth", aoi + "_DSM.txt")).read().split()]
    corners = [(e0 + i * size * gsd, n0 + j * size * gsd) for i in (0, 1) for j in (0, 1)]
    lonlat = np.array(utm_to_geodetic(epsg).TransformPoints(corners))
    east, north = enu_of_geodetic(origin, lonlat[:, 0], lonlat[:, 1])
    return east.min(), north.min(), east.max(), north.max()


def aois_under_core(root, spec, origin, epsg, min_overlap_m=1.0):
    """The AOIs whose truth grid overlaps the tile's core by more than min_overlap_m on both axes."""
    c = spec["core"]
    out = []
    for aoi in spec["aois"]:
        e0, n0, e1, n1 = truth_box_enu(root, aoi, origin, epsg)
        if (min(e1, c["max_east_m"]) - max(e0, c["min_east_m"]) > min_overlap_m and
                min(n1, c["max_north_m"]) - max(n0, c["min_north_m"]) > min_overlap_m):
            out.append(aoi)
    return out


def jobs(root, run):
    for city_dir in city_dirs(run):
        _, origin, specs = tiles_of(city_dir)
        for d, spec in specs:
            if os.path.exists(os.path.join(d, "splat", "scene.ply")):
                for aoi in aois_under_core(root, spec, origin, epsg_of(d)):
                    print(spec["id"], d, aoi, epsg_of(d))


def tileset_stats(tileset_path):
    """Bytes of the tileset folder and its depth (levels of tiles below the root, the root counted)."""
    folder = os.path.dirname(tileset_path)
    size = sum(os.path.getsize(os.path.join(dp, f)) for dp, _, fs in os.walk(folder) for f in fs)

    def depth(tile):
        return 1 + max((depth(c) for c in tile.get("children", [])), default=0)
    return size, depth(json.load(open(tileset_path))["root"])


def time_peak_mb(path):
    """Maximum resident set size [MiB] from a `/usr/bin/time -v` log, or None."""
    if not os.path.exists(path):
        return None
    for line in open(path):
        if "Maximum resident set size" in line:
            return int(line.split(":")[1]) / 1024.0
    return None


def viewer_figures(path):
    """web/check_city_view.mjs's report, trimmed to its figures, or None."""
    if not os.path.exists(path):
        return None
    v = json.load(open(path))
    keep = ("seconds_to_tiles_loaded", "seconds_to_complete_frame", "contents", "bytes", "contents_by_depth",
            "tileset_visible_fraction", "all_tiles_loaded")
    return {"streams": v["streams"], "contents_per_depth": v["contents_per_depth"],
            "errors": v["errors"] + v["external"],
            **{view: {k: v[view].get(k) for k in keep} for view in ("whole_city", "street")}}


def adjacent_aois(corners):
    """Pairs (a, b, side) of AOIs whose grids touch, b north or east of a. `corners` maps
    each AOI to (x, y, rows, cols): its upper-left corner in cells and its shape."""
    pairs = []
    for a, (ax, ay, rows, cols) in corners.items():
        for b, (bx, by, _, _) in corners.items():
            if (bx, by) == (ax, ay + rows):
                pairs.append((a, b, "north"))
            elif (bx, by) == (ax + cols, ay):
                pairs.append((a, b, "east"))
    return pairs


def error_seams(root, run, aois):
    """Steps of the DSM's error across the borders between adjacent AOIs, against the same
    steps inside them.

    The merge's seam metric steps the heights, so a border the seam line lays along a wall
    has the wall's step, which the truth has too. Here only pairs of adjacent cells whose
    truth is smooth (steps less than SMOOTH_TRUTH_STEP_M) count, and what steps is the error
    (prediction minus truth, each AOI on its own truth grid, row 0 north, no comparison
    shift): a step the prediction has where the truth has none, which a seam adds. Where
    the truth steps (a wall), the wall's placement decides the error's step: counted, a
    border that runs along a wall holds little else. A border's interior reference: every
    such pair in the same direction inside its two AOIs."""
    grids = {}
    for aoi in aois:
        pred = gdal.Open(os.path.join(run, aoi, "dsm.tif"))
        truth = gdal.Open(os.path.join(root, "Track3-Truth", aoi + "_DSM.tif"))
        p = pred.GetRasterBand(1).ReadAsArray().astype(np.float64)
        t = truth.GetRasterBand(1).ReadAsArray().astype(np.float64)
        if p.shape != t.shape:
            sys.exit(f"bench_city: {aoi}: dsm.tif {p.shape} and its truth {t.shape} are not on one grid")
        t[t < -1000] = np.nan  # DFC2019 truth no-data (-9999)
        gt = pred.GetGeoTransform()
        grids[aoi] = (round(gt[0] / gt[1]), round(gt[3] / gt[1]), p - t, t)  # corner in cells, error, truth
    def smooth(error_step, truth_step):
        return np.where(np.abs(truth_step) < SMOOTH_TRUTH_STEP_M, error_step, np.nan).ravel()
    def inner(e, t, axis):
        return smooth(np.diff(e, axis=axis), np.diff(t, axis=axis))
    def mean_abs(d):
        d = np.abs(d)
        return float(np.nanmean(d)) if np.isfinite(d).any() else None
    borders = []
    for a, b, side in adjacent_aois({k: (x, y) + e.shape for k, (x, y, e, _) in grids.items()}):
        (_, _, ea, ta), (_, _, eb, tb) = grids[a], grids[b]
        if eb.shape != ea.shape:
            continue
        if side == "north":
            across = smooth(eb[-1, :] - ea[0, :], tb[-1, :] - ta[0, :])
            inside = [inner(ea, ta, 0), inner(eb, tb, 0)]
        else:
            across = smooth(eb[:, 0] - ea[:, -1], tb[:, 0] - ta[:, -1])
            inside = [inner(ea, ta, 1), inner(eb, tb, 1)]
        step, interior = mean_abs(across), mean_abs(np.concatenate(inside))
        borders.append({"aois": [a, b], "pairs": int(np.isfinite(across).sum()), "mean_error_step_m": step,
                        "interior_mean_error_step_m": interior,
                        "ratio": step / interior if step is not None and interior else None})
    steps = [b["mean_error_step_m"] * b["pairs"] for b in borders if b["mean_error_step_m"] is not None]
    pairs = sum(b["pairs"] for b in borders if b["mean_error_step_m"] is not None)
    interior = [inner(e, t, k) for _, _, e, t in grids.values() for k in (0, 1)]
    interior_mean = mean_abs(np.concatenate(interior)) if interior else None
    boundary_mean = sum(steps) / pairs if pairs else None
    return {"boundary_mean_error_step_m": boundary_mean, "interior_mean_error_step_m": interior_mean,
            "ratio": boundary_mean / interior_mean if boundary_mean is not None and interior_mean else None,
            "borders": borders}


def synth_options(root):
    """The `skyfall synth` options the city was made with (its synth_report.json)."""
    try:
        with open(os.path.join(root, "synth_report.json")) as f:
            return json.load(f).get("options")
    except (OSError, ValueError):
        return None


def aoi_frames(root, run, aois):
    """The vertical frame each AOI's DSM lands in: the median of prediction minus truth over
    its ground cells (truth class 2; every cell without a class raster), no comparison shift
    and no offset removed. The per-AOI comparisons remove their own shift and offset, so a
    city whose tiles' bundle adjustments fixed different frames scores as well there as one
    in a single frame; these offsets, and their differences across each border between
    adjacent AOIs, show it. The merged DSM spreads such a step over the seam's few cells
    (a ramp, often a gap), which the error steps of adjacent cells see only in part."""
    grids, offsets = {}, {}
    for aoi in aois:
        pred = gdal.Open(os.path.join(run, aoi, "dsm.tif"))
        p = pred.GetRasterBand(1).ReadAsArray().astype(np.float64)
        truth = gdal.Open(os.path.join(root, "Track3-Truth", aoi + "_DSM.tif"))  # kept open while its band is read
        t = truth.GetRasterBand(1).ReadAsArray().astype(np.float64)
        d = p - t
        d[t < -1000] = np.nan  # DFC2019 truth no-data (-9999)
        cls_path = os.path.join(root, "Track3-Truth", aoi + "_CLS.tif")
        if os.path.exists(cls_path):
            classes = gdal.Open(cls_path)
            d[classes.GetRasterBand(1).ReadAsArray() != 2] = np.nan
        offsets[aoi] = float(np.nanmedian(d)) if np.isfinite(d).any() else None
        gt = pred.GetGeoTransform()
        grids[aoi] = (round(gt[0] / gt[1]), round(gt[3] / gt[1])) + p.shape
    borders = [{"aois": [a, b], "step_m": offsets[b] - offsets[a]} for a, b, _ in adjacent_aois(grids)
               if offsets[a] is not None and offsets[b] is not None]
    known = [v for v in offsets.values() if v is not None]
    return {"offsets_m": offsets, "spread_m": max(known) - min(known) if known else None,
            "largest_border_step_m": max((abs(b["step_m"]) for b in borders), default=None), "borders": borders}


def figures(km, n, block_m, root, run, out, json_name, executor):
    wall = float(open(os.path.join(run, "wall_seconds")).read())
    resumed = os.path.exists(os.path.join(run, "resumed")) and open(os.path.join(run, "resumed")).read().strip() == "true"
    # Sittings: the run stopped and finished again (bench_city.sh), its time their sum.
    sittings_file = os.path.join(run, "sittings")
    sittings = int(open(sittings_file).read()) if os.path.exists(sittings_file) else 1
    area_km2 = (n * block_m / 1000.0) ** 2
    cities = city_dirs(run)
    if len(cities) != 1:
        sys.exit(f"bench_city: expected one city under {run}, found {len(cities)}")
    city_dir = cities[0]
    report = json.load(open(os.path.join(city_dir, "run_report.json")))
    merge_report = json.load(open(os.path.join(city_dir, "scene", "merge_report.json")))
    index, origin, specs = tiles_of(city_dir)
    epsg = epsg_of(specs[0][0])

    # Time and memory. City stages in run order; per-tile stages summed over
    # the tiles (process time of each, two tiles at a time on 2 cores).
    stage_seconds = {}
    for s in report["stages"]:
        name = "products" if s["stage"].startswith("products") else s["stage"]
        stage_seconds[name] = stage_seconds.get(name, 0.0) + s["seconds"]
    tile_stage_seconds = {}
    for t in report["tiles"]:
        for s in t.get("stages", []):
            tile_stage_seconds[s["stage"]] = tile_stage_seconds.get(s["stage"], 0.0) + s["seconds"]
    peak = {s["stage"]: s.get("peak_rss_mb") for s in report["stages"]}
    tiles_ok = [t for t in report["tiles"] if t.get("status") == "ok"]
    tileset_bytes, tileset_depth = tileset_stats(report["tiles3d"]["tileset"]) if "tiles3d" in report else (None, None)

    # DSM error: per AOI error map (prediction minus truth after the
    # comparison's shift and vertical offset), pooled over the city.
    all_err, border_err = [], []
    per_tile_city = {spec["id"]: [] for _, spec in specs}
    for aoi in report["aois"]:
        err, east, north = raster_enu(os.path.join(run, aoi, "dsm_compare", "error_map.tif"), origin, epsg)
        ok = np.isfinite(err)
        all_err.append(np.abs(err[ok]))
        near = ok & (border_distance(specs[0][1]["grid"], east, north) <= BORDER_BAND_M)
        border_err.append(np.abs(err[near]))
        for _, spec in specs:
            m = ok & in_core(spec, east, north)
            per_tile_city[spec["id"]].append(np.abs(err[m]))
    all_err, border_err = np.concatenate(all_err), np.concatenate(border_err)

    # Each tile alone: its reconstruction compared with the truth of the
    # AOIs its core touches, over its core.
    single, single_border = {}, []
    for d, spec in specs:
        parts = []
        for aoi in aois_under_core(root, spec, origin, epsg):
            path = os.path.join(out, "single_tile", spec["id"], aoi, "compare", "error_map.tif")
            if not os.path.exists(path):
                continue
            err, east, north = raster_enu(path, origin, epsg)
            m = np.isfinite(err) & in_core(spec, east, north)
            parts.append(np.abs(err[m]))
            near = m & (border_distance(spec["grid"], east, north) <= BORDER_BAND_M)
            single_border.append(np.abs(err[near]))
        if parts and sum(p.size for p in parts):
            single[spec["id"]] = float(np.concatenate(parts).mean())
    city_tile = {k: float(np.concatenate(v).mean()) for k, v in per_tile_city.items() if sum(p.size for p in v)}

    seam = merge_report["seam"]
    doc = {
        "km": km, "executor": executor, "aois": n * n, "aoi_side_m": block_m, "area_km2": area_km2, "cores": os.cpu_count(),
        "city_options": synth_options(root),
        "resumed": resumed, "sittings": sittings,
        "seconds": wall, "seconds_per_km2": wall / area_km2,
        "stage_seconds": stage_seconds, "tile_stage_seconds_summed": tile_stage_seconds,
        "tiles": len(report["tiles"]), "tiles_ok": len(tiles_ok),
        "tile_seconds_mean": float(np.mean([t["tile_seconds"] for t in tiles_ok])) if tiles_ok else None,
        # tile: the largest tile process; merge, export: each run alone in its
        # own process (bench_city.sh); the run's own high-water marks beside.
        "peak_rss_mb": {"tile": max((t.get("peak_rss_mb", 0) for t in report["tiles"]), default=None),
                        "merge": time_peak_mb(os.path.join(out, "merge.time")),
                        "export": time_peak_mb(os.path.join(out, "export.time"))},
        "run_high_water_mb": {"merge": peak.get("merge"),
                              "products": max((v for k, v in peak.items() if k.startswith("products") and v),
                                              default=None),
                              "3dtiles": peak.get("3dtiles")},
        "viewer": viewer_figures(os.path.join(out, "viewer", "check.json")),
        "gaussians_per_level": [lvl["count"] for lvl in merge_report["lod"]],
        "tileset_bytes": tileset_bytes, "tileset_depth": tileset_depth,
        "city_mae_m": float(all_err.mean()), "city_cells": int(all_err.size),
        "mean_tile_mae_m": float(np.mean(list(single.values()))) if single else None,
        "single_tile_mae_m": single,
        "city_mae_by_tile_core_m": city_tile,
        "border_mae_m": float(border_err.mean()) if border_err.size else None,
        "border_cells": int(border_err.size), "border_band_m": BORDER_BAND_M,
        # The same band from the tiles' own reconstructions, each over its core:
        # what the border cells cost before the merge (hard content near a
        # border raises both; a seam raises the city's alone).
        "single_tile_border_mae_m": float(np.concatenate(single_border).mean())
        if single_border and sum(p.size for p in single_border) else None,
        "seams": {"ratio": seam["ratio"], "boundary_mean_step_m": seam["boundary_mean_step_m"],
                  "interior_mean_step_m": seam["interior_mean_step_m"], "borders": seam.get("borders", [])},
        # The merge's metric steps heights; this one steps the error (error_seams).
        "error_seams": error_seams(root, run, report["aois"]),
        "aoi_frames": aoi_frames(root, run, report["aois"]),
        "dsm_mae_m_by_aoi": {d["aoi"]: d["mae_m"] for d in report.get("dsm", [])},
    }
    if doc["mean_tile_mae_m"]:
        doc["city_over_mean_tile"] = doc["city_mae_m"] / doc["mean_tile_mae_m"]
    if doc["border_mae_m"]:
        doc["border_over_city"] = doc["border_mae_m"] / doc["city_mae_m"]
    tmp = os.path.join(out, json_name + ".tmp")
    with open(tmp, "w") as f:
        json.dump(doc, f, indent=1)
    os.replace(tmp, os.path.join(out, json_name))

    fmt = lambda v, f="{:.3f}": "n/a" if v is None else f.format(v)
    print(f"city {n}x{n} AOIs of {block_m:.0f} m ({area_km2:.3f} km^2), {doc['tiles_ok']}/{doc['tiles']} tiles ok"
          + (" (resumed: the time is not a whole run)" if resumed else "")
          + (f" (in {sittings} sittings: the time is their sum, tiles a stop cut short redone)" if sittings > 1 else ""))
    print(f"  time {wall:.0f} s = {wall / area_km2 / 60:.1f} min per km^2; stages: "
          + ", ".join(f"{k} {v:.0f} s" for k, v in stage_seconds.items()))
    print("  tile stages summed: " + ", ".join(f"{k} {v:.0f} s" for k, v in tile_stage_seconds.items()))
    print(f"  peak RSS [MiB]: tile {fmt(doc['peak_rss_mb']['tile'], '{:.0f}')}, merge "
          f"{fmt(doc['peak_rss_mb']['merge'], '{:.0f}')}, export {fmt(doc['peak_rss_mb']['export'], '{:.0f}')}")
    if doc["viewer"]:
        w, st = doc["viewer"]["whole_city"], doc["viewer"]["street"]
        print(f"  viewer: whole city {w['contents']} contents, {w['bytes'] / 1e6:.2f} MB, frame at "
              f"{w['seconds_to_complete_frame']:.1f} s; street {st['contents']} more, {st['bytes'] / 1e6:.2f} MB, "
              f"frame at {st['seconds_to_complete_frame']:.1f} s; streams: {doc['viewer']['streams']}")
    print(f"  Gaussians per level {doc['gaussians_per_level']}; tileset {fmt(tileset_bytes, '{:d}')} bytes, "
          f"depth {fmt(tileset_depth, '{:d}')}")
    print(f"  DSM MAE: city {doc['city_mae_m']:.3f} m, mean single tile {fmt(doc['mean_tile_mae_m'])} m, "
          f"within {BORDER_BAND_M:.0f} m of interior borders {fmt(doc['border_mae_m'])} m "
          f"({doc['border_cells']} cells; the tiles alone there {fmt(doc['single_tile_border_mae_m'])} m)")
    print(f"  seams: ratio {fmt(seam['ratio'])}, boundary {fmt(seam['boundary_mean_step_m'])} m, "
          f"interior {fmt(seam['interior_mean_step_m'])} m, worst border ratio "
          f"{fmt(max((b['ratio'] or 0 for b in doc['seams']['borders']), default=None))}")
    es = doc["error_seams"]
    worst = max(es["borders"], key=lambda b: b["ratio"] or 0, default=None)
    print(f"  error steps across AOI borders: {fmt(es['boundary_mean_error_step_m'])} m against "
          f"{fmt(es['interior_mean_error_step_m'])} m inside (ratio {fmt(es['ratio'])})"
          + (f"; worst {worst['aois'][0]}|{worst['aois'][1]} {fmt(worst['mean_error_step_m'])} m against "
             f"{fmt(worst['interior_mean_error_step_m'])} m" if worst else ""))
    fr = doc["aoi_frames"]
    offsets = ", ".join(f"{aoi} {fmt(v, '{:+.2f}')}" for aoi, v in fr["offsets_m"].items())
    print(f"  AOI frames (ground, prediction minus truth): {offsets} m; spread {fmt(fr['spread_m'])} m, "
          f"largest step across a border {fmt(fr['largest_border_step_m'])} m")
    print("bench_city: wrote " + os.path.join(out, json_name))


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "jobs":
        jobs(sys.argv[2], sys.argv[3])
    elif len(sys.argv) == 10 and sys.argv[1] == "figures":
        figures(float(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), *sys.argv[5:10])
    else:
        sys.exit(__doc__)
