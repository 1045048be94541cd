"""relief.read / relief.write with rasterio: arrays, transforms and CRSs round trip."""

from __future__ import annotations

import numpy as np
import pytest

import relief
from conftest import FIXTURE

rasterio = pytest.importorskip("rasterio")
from affine import Affine  # noqa: E402
from rasterio.windows import Window, transform as wtransform  # noqa: E402


def test_read_matches_rasterio():
    r = relief.read(FIXTURE)
    with rasterio.open(FIXTURE) as src:
        a = src.read(1).astype(np.float32)
        assert r.transform == src.transform
        assert rasterio.crs.CRS.from_wkt(r.crs) == src.crs
    assert r.array.dtype == np.float32 and r.array.shape == (512, 512)
    np.testing.assert_array_equal(r.array, a)
    # EPSG:3857 pixels of 76.437 m are 61.70 m on the ground at the tile's latitude.
    assert r.cell_size[0] == pytest.approx(61.70, abs=0.01)
    assert relief.ground_cell_size(r.transform, r.crs, 512) == r.cell_size


def test_rasterio_crop_of_the_shared_dem_round_trips(shared_srtm, tmp_path):
    with rasterio.open(shared_srtm) as src:
        w = Window(300, 100, 64, 48)
        a = src.read(1, window=w)
        t = wtransform(w, src.transform)
        crs = src.crs
    out = tmp_path / "alps_crop.tif"
    # rasterio's values go straight in: the array, src.transform, src.crs.
    relief.write(out, a, t, crs)
    with rasterio.open(out) as back:
        np.testing.assert_array_equal(back.read(1), a.astype(np.float32))
        assert back.transform == t
        assert back.crs == crs
    r = relief.read(out)
    assert r.transform == t
    np.testing.assert_array_equal(r.array, a.astype(np.float32))
    # Geographic: relief's ground cell size at the crop's centre latitude (~47.9 N).
    assert r.cell_size[0] == pytest.approx(3 * 30.87 * np.cos(np.radians(47.9)), rel=0.01)


def test_any_crs_read_by_relief_is_written_back(shared_dem, tmp_path):
    # alps_dem's CRS is ETRS89 in arc-seconds (no EPSG code): its GeoTIFF keys pass through.
    r = relief.read(shared_dem)
    out = tmp_path / "alps.tif"
    relief.write(out, r)
    with rasterio.open(out) as back, rasterio.open(shared_dem) as src:
        assert back.crs == src.crs
        assert back.transform == src.transform
        np.testing.assert_array_equal(back.read(1), src.read(1).astype(np.float32))


def test_write_takes_wkt_and_a_raster(tmp_path):
    r = relief.read(FIXTURE)
    out = tmp_path / "again.tif"
    relief.write(out, r)
    with rasterio.open(out) as back, rasterio.open(FIXTURE) as src:
        assert back.crs == src.crs
        assert back.transform == src.transform
        np.testing.assert_array_equal(back.read(1), src.read(1).astype(np.float32))


def test_amplified_raster_keeps_the_georeference(crop, tmp_path):
    src = relief.read(crop)
    out = relief.amplify(src, FIXTURE, 4, seed=1)
    assert isinstance(out, relief.Raster)
    assert out.array.shape == (32 * 4, 40 * 4)
    assert out.transform == src.transform @ Affine.scale(0.25)
    path = tmp_path / "x4.tif"
    relief.write(path, out)
    with rasterio.open(path) as back, rasterio.open(crop) as orig:
        assert back.crs == orig.crs
        assert back.transform == orig.transform @ Affine.scale(0.25)
        assert back.bounds == orig.bounds
        np.testing.assert_array_equal(back.read(1), out.array)


def test_npy_output_is_the_array(tmp_path):
    a = np.arange(12, dtype=np.float32).reshape(3, 4)
    relief.write(tmp_path / "a.npy", a)
    np.testing.assert_array_equal(np.load(tmp_path / "a.npy"), a)
    back = relief.read(tmp_path / "a.npy")
    np.testing.assert_array_equal(back.array, a)
