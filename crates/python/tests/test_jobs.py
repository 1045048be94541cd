"""quilt, synthesize, volume, erode and masks from Python; quilt equal to the CLI's bytes."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

import relief
from conftest import FIXTURE


def same_bits(a, b):
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


def test_quilt_equals_the_cli(relief_bin, tmp_path):
    out = tmp_path / "q.npy"
    subprocess.run([str(relief_bin), "quilt", str(out), "--exemplar", str(FIXTURE), "--guide-from",
                    str(FIXTURE), "--blur", "4", "--seed", "3"], check=True, capture_output=True)
    py = relief.quilt([FIXTURE], guide=FIXTURE, guide_setup={"blur": 4.0}, seed=3)
    assert same_bits(np.load(out), py)


def test_volume_mesh_covers_the_dem():
    r = relief.read(FIXTURE)
    small = relief.Raster(r.array[:96, :96].copy(), cell_size=r.cell_size)
    v, f = relief.volume(small, features=["arches"], max_mesh_cells=96, seed=2)
    assert v.dtype == np.float32 and v.shape[1] == 3
    assert f.dtype == np.uint32 and f.shape[1] == 3 and len(f) > 1000
    assert f.max() < len(v)
    cx, cy = r.cell_size
    # Metres: the mesh spans the crop's ground extent and its elevation range.
    assert v[:, 0].max() - v[:, 0].min() == pytest.approx(95 * cx, rel=0.05)
    assert v[:, 1].max() - v[:, 1].min() == pytest.approx(95 * cy, rel=0.05)
    assert v[:, 2].max() == pytest.approx(float(small.array.max()), abs=cx * 2)
    # Vertex colours on request: one sRGB + alpha per vertex, the same mesh.
    v2, f2, c = relief.volume(small, features=["arches"], max_mesh_cells=96, seed=2, colours=True)
    assert np.array_equal(v2, v) and np.array_equal(f2, f)
    assert c.dtype == np.uint8 and c.shape == (len(v), 4) and (c[:, 3] == 255).all()
    assert len(np.unique(c[:, :3], axis=0)) > 10


def test_erode_and_masks():
    r = relief.read(FIXTURE)
    dem = relief.Raster(r.array[:128, :128].copy(), cell_size=r.cell_size)
    e = relief.erode(dem, years=2000.0, hydraulic_iterations=0, thermal_iterations=0)
    assert e["terrain"].shape == (128, 128)
    # What was removed and laid down is the difference of the terrains.
    diff = e["terrain"].astype(np.float64) - dem.array
    assert np.allclose(e["deposition"] - e["erosion"], diff, atol=1e-2)
    assert not np.array_equal(e["terrain"], dem.array)
    m = relief.masks(dem)
    assert m["splat"].shape == (128, 128, 4)
    assert np.allclose(m["splat"].sum(axis=2), 1.0, atol=1e-4)


def test_synthesize_follows_river_and_ridge_strokes():
    y, x = np.mgrid[0:16, 0:16].astype(np.float32)
    sketch = np.exp(-((x - 7.5) ** 2 + (y - 7.5) ** 2) / 40.0).astype(np.float32)
    river = np.where((x == 11) & (y >= 7), 1.0, 0.0).astype(np.float32)
    kw = dict(steps=2, seed=1, sketch_cell_size=[1000.0, 1000.0], height_range=[0.0, 2000.0])
    plain = relief.synthesize(sketch, FIXTURE, **kw)
    cut = relief.synthesize(sketch, FIXTURE, rivers=river, **kw)
    corridor = (slice(8 * 16, 13 * 16), slice(11 * 16, 12 * 16))
    assert cut[corridor].mean() < plain[corridor].mean() - 100.0
    with pytest.raises(ValueError, match="river strokes"):
        relief.synthesize(sketch, FIXTURE, rivers=river[:5, :5], **kw)


def test_synthesize_from_a_sketch():
    sketch = np.zeros((16, 16), np.float32)
    sketch[4:12, 6:10] = 1.0
    out = relief.synthesize(sketch, FIXTURE, steps=2, seed=1)
    assert out.shape == (256, 256)
    assert np.isfinite(out).all() and out.std() > 1.0
    again = relief.synthesize(sketch, FIXTURE, steps=2, seed=1)
    assert same_bits(out, again)
