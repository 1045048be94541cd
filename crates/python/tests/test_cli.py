"""The Python jobs give the bytes `relief` (the CLI cargo built) writes for the same call."""

from __future__ import annotations

import subprocess
import time

import numpy as np

import relief
from conftest import FIXTURE


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


def cli(relief_bin, *args) -> float:
    t = time.perf_counter()
    subprocess.run([str(relief_bin), *map(str, args)], check=True, capture_output=True)
    return time.perf_counter() - t


def test_amplify_equals_the_cli(relief_bin, crop, tmp_path):
    out = tmp_path / "cli.npy"
    cli(relief_bin, "amplify", crop, out, "--exemplar", FIXTURE, "--factor", 16, "--seed", 1)
    py = relief.amplify(relief.read(crop), FIXTURE, 16, seed=1)
    assert same_bits(np.load(out), py.array)


def test_amplify_paper_and_settings_equal_the_cli(relief_bin, crop, tmp_path):
    out = tmp_path / "cli.npy"
    cli(relief_bin, "amplify", crop, out, "--exemplar", FIXTURE, "--factor", 4, "--seed", 7,
        "--paper", "--radius", 3, "--atoms", 0)
    py = relief.amplify(crop, FIXTURE, 4, seed=7, paper=True, radius=3, dictionary="complete")
    assert same_bits(np.load(out), py.array)


def test_amplify_window_equals_the_cli(relief_bin, crop, tmp_path):
    out = tmp_path / "cli.npy"
    cli(relief_bin, "amplify", crop, out, "--exemplar", FIXTURE, "--factor", 16, "--seed", 1,
        "--window", "100,60,200,150")
    py = relief.amplify(crop, FIXTURE, 16, seed=1, window=(100, 60, 200, 150))
    assert same_bits(np.load(out), py.array)


def test_refine_equals_the_cli(relief_bin, crop, tmp_path):
    out = tmp_path / "cli.npy"
    cli(relief_bin, "refine", crop, out, "--levels", 3, "--seed", 5)
    py = relief.refine(relief.read(crop), extra_levels=3, seed=5)
    assert same_bits(np.load(out), py.array)


def test_flow_equals_the_cli(relief_bin, crop, tmp_path):
    cli(relief_bin, "flow", crop, "--out", tmp_path)
    py = relief.flow(relief.read(crop))
    files = {"conditioned": "filled", "direction": "direction", "area": "area",
             "strahler": "strahler", "watersheds": "watersheds", "hand": "hand"}
    for name, file in files.items():
        cli_r = relief.read(tmp_path / f"{file}.tif").array
        assert same_bits(cli_r, py[name]), name
    assert py["channels"]["type"] == "FeatureCollection"
