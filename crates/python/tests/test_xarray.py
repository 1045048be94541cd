"""The xarray accessor keeps coordinates and the rioxarray CRS."""

from __future__ import annotations

import numpy as np
import pytest

import relief
from conftest import FIXTURE

rioxarray = pytest.importorskip("rioxarray")


def test_accessor_amplify_keeps_coordinates_and_crs(crop):
    da = rioxarray.open_rasterio(crop).squeeze("band", drop=True).astype("float32")
    out = da.relief.amplify(FIXTURE, 4, seed=1)
    src = relief.read(crop)
    np.testing.assert_array_equal(out.values, relief.amplify(src, FIXTURE, 4, seed=1).array)
    assert out.rio.crs == da.rio.crs
    # Same outer edges, cells a quarter of the size.
    want = da.rio.transform() @ __import__("affine").Affine.scale(0.25)
    assert out.rio.transform().almost_equals(want, precision=1e-9), (out.rio.transform(), want)
    assert out.rio.bounds() == pytest.approx(da.rio.bounds())
    # The ground cell size relief uses is the GeoTIFF reader's (Web Mercator scaled).
    assert da.relief.cell_size() == pytest.approx(src.cell_size)


def test_accessor_flow_is_a_dataset_on_the_same_grid(crop):
    da = rioxarray.open_rasterio(crop).squeeze("band", drop=True).astype("float32")
    ds = da.relief.flow()
    assert set(ds.data_vars) >= {"conditioned", "area", "direction"}
    np.testing.assert_array_equal(ds.x.values, da.x.values)
    assert ds["area"].rio.crs == da.rio.crs
    assert ds.attrs["channels"]["type"] == "FeatureCollection"
