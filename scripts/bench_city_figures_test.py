#!/usr/bin/python3
"""Tests of scripts/bench_city_figures.py's error_seams: the error's steps across the
border between two adjacent AOIs, counted where the truth is smooth. (Debian's python3:
GDAL and NumPy come with python3-gdal.)"""
import importlib.util
import os
import tempfile
import unittest

import numpy as np
from osgeo import gdal

HERE = os.path.dirname(os.path.abspath(__file__))
spec = importlib.util.spec_from_file_location("bench_city_figures", os.path.join(HERE, "bench_city_figures.py"))
figures = importlib.util.module_from_spec(spec)
spec.loader.exec_module(figures)

GSD_M = 0.5
SIDE = 8  # cells per AOI side


def write(path, array, x0_m, y_top_m):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    ds = gdal.GetDriverByName("GTiff").Create(path, array.shape[1], array.shape[0], 1, gdal.GDT_Float32)
    ds.SetGeoTransform((x0_m, GSD_M, 0.0, y_top_m, 0.0, -GSD_M))
    ds.GetRasterBand(1).WriteArray(array.astype(np.float32))
    ds.FlushCache()


class CityFolders(unittest.TestCase):
    """A DFC-style city folder (truth) and a run folder (predictions) in a scratch directory."""

    def setUp(self):
        self.dir = tempfile.TemporaryDirectory()
        self.root, self.run = os.path.join(self.dir.name, "city"), os.path.join(self.dir.name, "run")

    def tearDown(self):
        self.dir.cleanup()

    def aoi(self, name, x0_m, truth, pred, cls=None):
        truth_dir = os.path.join(self.root, "Track3-Truth")
        write(os.path.join(truth_dir, name + "_DSM.tif"), truth, 0.0, float(SIDE))  # DFC: no georeference
        if cls is not None:
            write(os.path.join(truth_dir, name + "_CLS.tif"), cls, 0.0, float(SIDE))
        write(os.path.join(self.run, name, "dsm.tif"), pred, x0_m, 1000.0)


class ErrorSeams(CityFolders):

    def test_a_jump_where_the_truth_is_smooth_counts_and_a_wall_does_not(self):
        rows, cols = np.mgrid[0:SIDE, 0:SIDE]
        noise = 0.1 * ((rows + cols) % 2)  # every step inside is 0.1 m
        # West AOI: flat ground, and a 20 m wall between its columns 2 and 3 that the
        # prediction puts one cell east (an error step of 20 m inside, on a wall pair).
        west_truth = np.where(cols >= 3, 20.0, 0.0)
        west_pred = np.where(cols >= 4, 20.0, 0.0) + noise
        # East AOI, its west edge on the border: a 30 m wall on the border itself in rows
        # 0-3 (the truth steps there), ground in rows 4-7 whose first column the
        # prediction lifts by 5 m (a seam where the truth is smooth).
        east_truth = np.where(rows < 4, 50.0, 20.0) * (cols >= 0)
        east_pred = east_truth + noise + np.where((rows >= 4) & (cols == 0), 5.0, 0.0)
        self.aoi("A_X0Y0", 0.0, west_truth, west_pred)
        self.aoi("A_X1Y0", SIDE * GSD_M, east_truth, east_pred)
        seams = figures.error_seams(self.root, self.run, ["A_X0Y0", "A_X1Y0"])
        self.assertEqual(len(seams["borders"]), 1)
        border = seams["borders"][0]
        self.assertEqual(border["aois"], ["A_X0Y0", "A_X1Y0"])
        # Rows 4-7 cross the border on smooth truth (20 m both sides); rows 0-3 are wall pairs.
        self.assertEqual(border["pairs"], 4)
        # The noise alternates by 0.1 m from row to row across the border (columns 7 and 0
        # differ in parity), so the mean step is the seam's 5 m.
        self.assertAlmostEqual(border["mean_error_step_m"], 5.0, places=5)
        # Inside: every east-west pair of the two AOIs whose truth steps less than 1 m,
        # counted here cell by cell. The misplaced wall's pair where the truth steps
        # (columns 2-3 of the west) is left out; its pair where the prediction steps and
        # the truth does not (columns 3-4) counts.
        steps = []
        for truth, pred in ((west_truth, west_pred), (east_truth, east_pred)):
            for r in range(SIDE):
                for c in range(SIDE - 1):
                    if abs(truth[r, c + 1] - truth[r, c]) < figures.SMOOTH_TRUTH_STEP_M:
                        steps.append(abs((pred[r, c + 1] - truth[r, c + 1]) - (pred[r, c] - truth[r, c])))
        self.assertEqual(len(steps), 2 * SIDE * (SIDE - 1) - SIDE)  # one wall pair per west row
        self.assertAlmostEqual(border["interior_mean_error_step_m"], float(np.mean(steps)), places=5)
        self.assertAlmostEqual(border["ratio"], 5.0 / float(np.mean(steps)), places=5)
        # The overall figure pools every border's pairs and every inside pair both ways.
        self.assertAlmostEqual(seams["boundary_mean_error_step_m"], 5.0, places=5)

    def test_aois_that_do_not_touch_have_no_border_and_grids_must_agree(self):
        flat = np.zeros((SIDE, SIDE))
        self.aoi("B_X0Y0", 0.0, flat, flat)
        self.aoi("B_X2Y0", 2 * SIDE * GSD_M, flat, flat)  # a gap of one AOI
        self.assertEqual(figures.error_seams(self.root, self.run, ["B_X0Y0", "B_X2Y0"])["borders"], [])
        self.aoi("B_X1Y0", SIDE * GSD_M, flat, np.zeros((SIDE, SIDE + 1)))
        with self.assertRaises(SystemExit):
            figures.error_seams(self.root, self.run, ["B_X1Y0"])


class AoiFrames(CityFolders):
    def test_each_aoi_is_offset_by_its_ground_median_and_borders_step_by_the_difference(self):
        rows, cols = np.mgrid[0:SIDE, 0:SIDE]
        truth = np.where(cols >= 5, 30.0, 10.0)  # ground west of column 5, a roof east of it
        cls = np.where(cols >= 5, 6, 2).astype(np.float64)
        # West AOI 1 m high on its ground (its roof 4 m low: not ground, not counted);
        # east AOI 2 m low, one ground cell an outlier the median ignores.
        west = truth + np.where(cols >= 5, -4.0, 1.0)
        east = truth + np.where(cols >= 5, 0.0, -2.0)
        east[0, 0] += 50.0
        for name, x0, pred in (("C_X0Y0", 0.0, west), ("C_X1Y0", SIDE * GSD_M, east)):
            self.aoi(name, x0, truth, pred, cls)
        frames = figures.aoi_frames(self.root, self.run, ["C_X0Y0", "C_X1Y0"])
        self.assertAlmostEqual(frames["offsets_m"]["C_X0Y0"], 1.0, places=5)
        self.assertAlmostEqual(frames["offsets_m"]["C_X1Y0"], -2.0, places=5)
        self.assertAlmostEqual(frames["spread_m"], 3.0, places=5)
        self.assertEqual(frames["borders"], [{"aois": ["C_X0Y0", "C_X1Y0"], "step_m": -3.0}])
        self.assertAlmostEqual(frames["largest_border_step_m"], 3.0, places=5)


if __name__ == "__main__":
    unittest.main()
