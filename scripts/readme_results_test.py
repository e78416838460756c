#!/usr/bin/env python3
"""Tests of scripts/readme_results.py: a run's table, and the dated record a
subset rerun updates without losing the other scenes' rows."""
import json
import os
import subprocess
import sys
import tempfile
import unittest

SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "readme_results.py")
README = "# Title\n\n<!-- results:begin -->\nold table\n<!-- results:end -->\n\nAfter.\n"


def scene(name, mae, tuned=False, without_trees=None):
    s = {"scene": name, "tuned_on": tuned, "mae_m": mae, "median_m": 0.05, "completeness": 0.995,
         "seconds": 300.0, "dense_mae_m": 9.9}
    if without_trees is not None:
        s["mae_without_trees_m"] = without_trees
    return s


class ReadmeResults(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.TemporaryDirectory()
        self.readme = os.path.join(self.dir.name, "README.md")
        with open(self.readme, "w") as f:
            f.write(README)

    def tearDown(self):
        self.dir.cleanup()

    def bench(self, name, date, commit, scenes):
        path = os.path.join(self.dir.name, name)
        with open(path, "w") as f:
            json.dump({"schema": "skyfall.bench_accuracy/1", "date": date, "commit": commit, "cores": 2,
                       "scenes": scenes}, f)
        return path

    def run_script(self, *args):
        subprocess.run([sys.executable, SCRIPT, *args, self.readme], check=True)
        with open(self.readme) as f:
            return f.read()

    def test_a_run_replaces_the_block_and_keeps_the_rest(self):
        text = self.run_script(self.bench("a.json", "2026-12-01", "abc1234", [scene("jax068", 1.1034, True, 1.0341)]))
        self.assertIn("on 2026-12-01, 2 cores", text)
        self.assertIn("| jax068 | tuned on | 1.10 | 1.03 | 0.05 | 99.5 | 300 |", text)
        self.assertNotIn("old table", text)
        self.assertTrue(text.startswith("# Title") and text.endswith("After.\n"))

    def test_a_subset_rerun_updates_its_rows_and_keeps_the_others_dated(self):
        record = os.path.join(self.dir.name, "record.json")
        first = self.bench("a.json", "2026-12-01", "abc1234", [scene("syn_b", 0.9), scene("jax068", 1.2, True)])
        second = self.bench("b.json", "2026-12-06", "def5678", [scene("syn_b", 0.7)])
        self.run_script("--record", record, first)
        text = self.run_script("--record", record, second)
        self.assertIn("| syn_b | held out | 0.70 | n/a | 0.05 | 99.5 | 300 | 2026-12-06 (def5678) |", text)
        self.assertIn("| jax068 | tuned on | 1.20 | n/a | 0.05 | 99.5 | 300 | 2026-12-01 (abc1234) |", text)
        self.assertLess(text.index("| jax068"), text.index("| syn_b"))  # tuned-on scenes first
        with open(record) as f:
            kept = json.load(f)
        self.assertEqual([s["scene"] for s in kept["scenes"]], ["jax068", "syn_b"])
        self.assertNotIn("dense_mae_m", kept["scenes"][0])  # only the table's fields are kept
        # The same inputs give the same README.
        self.assertEqual(self.run_script("--record", record, second), text)


if __name__ == "__main__":
    unittest.main()
