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


def assert_written_back(src, out):
    """`relief.read(src)` written to `out` by `relief.write` has the CRS, transform and values
    rasterio reads in `src`."""
    relief.write(out, relief.read(src))
    with rasterio.open(out) as back, rasterio.open(src) as want:
        assert back.crs == want.crs
        assert back.transform == want.transform
        np.testing.assert_array_equal(back.read(1), want.read(1).astype(np.float32))


def test_any_crs_read_by_relief_is_written_back(shared_dem, tmp_path):
    # alps_dem's CRS is ETRS89 in arc-seconds (no EPSG code): its GeoTIFF keys pass through.
    assert_written_back(shared_dem, tmp_path / "alps.tif")


def test_write_takes_wkt_and_a_raster(tmp_path):
    assert_written_back(FIXTURE, tmp_path / "again.tif")


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


CUSTOM_CRS = {
    "lambert conic 2SP": "+proj=lcc +lat_1=45 +lat_2=50 +lat_0=47 +lon_0=10 +x_0=700000 +y_0=6600000 +ellps=GRS80 +units=m",
    "lambert conic 1SP": "+proj=lcc +lat_1=46.8 +lat_0=46.8 +lon_0=2.33722917 +k_0=0.99987742 +x_0=600000 +y_0=2200000 +a=6378249.2 +b=6356515 +units=m",
    "transverse mercator, Bessel": "+proj=tmerc +lat_0=0 +lon_0=13.5 +k=0.9996 +x_0=500000 +y_0=0 +ellps=bessel +units=m",
    "transverse mercator, feet": "+proj=tmerc +lat_0=31 +lon_0=-110.1666666666667 +k=0.9999 +x_0=213360 +y_0=0 +ellps=GRS80 +units=ft",
    "albers": "+proj=aea +lat_1=29.5 +lat_2=45.5 +lat_0=23 +lon_0=-96 +x_0=0 +y_0=0 +ellps=GRS80 +units=m",
    "polar stereographic": "+proj=stere +lat_0=90 +lat_ts=70 +lon_0=-45 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m",
    "lambert azimuthal": "+proj=laea +lat_0=52 +lon_0=10 +x_0=4321000 +y_0=3210000 +ellps=GRS80 +units=m",
    "mercator 2SP": "+proj=merc +lat_ts=30 +lon_0=0 +x_0=0 +y_0=0 +ellps=WGS84 +units=m",
    "oblique stereographic": "+proj=sterea +lat_0=52.15616055555555 +lon_0=5.38763888888889 +k=0.9999079 +x_0=155000 +y_0=463000 +ellps=bessel +units=m",
}


@pytest.mark.parametrize("name", sorted(CUSTOM_CRS))
def test_a_crs_without_an_epsg_code_is_written_as_geotiff_keys(name, tmp_path):
    # rasterio (GDAL) reads the written file back as the same projection: the raster's corners
    # land on the same longitudes and latitudes through both CRSs.
    from rasterio.crs import CRS
    from rasterio.warp import transform as warp

    crs = CRS.from_proj4(CUSTOM_CRS[name])
    a = np.arange(32 * 40, dtype=np.float32).reshape(32, 40)
    t = Affine(30, 0, 100_000, 0, -30, 200_000)
    out = tmp_path / "custom.tif"
    # As WKT 1 text: a CRS object with an EPSG equivalent (GDAL finds 3035 for the LAEA one)
    # would be written by its code.
    relief.write(out, a, transform=t, crs=crs.to_wkt())
    with rasterio.open(out) as back:
        assert back.crs is not None, "the CRS was dropped"
        assert back.transform == t
        xs, ys = [100_000, 101_200, 100_000], [200_000, 199_040, 199_040]
        lon0, lat0 = warp(crs, "EPSG:4326", xs, ys)
        lon1, lat1 = warp(back.crs, "EPSG:4326", xs, ys)
        np.testing.assert_allclose(lon1, lon0, atol=1e-9)
        np.testing.assert_allclose(lat1, lat0, atol=1e-9)


def test_a_crs_that_cannot_be_written_is_an_error_not_a_silent_loss(tmp_path):
    from rasterio.crs import CRS

    a = np.zeros((8, 8), np.float32)
    t = Affine(30, 0, 0, 0, -30, 0)
    omerc = CRS.from_proj4(
        "+proj=omerc +lat_0=4 +lonc=102.25 +alpha=323.0257964666666 +k=0.99984 +x_0=804671 "
        "+y_0=0 +ellps=GRS80 +units=m"
    )
    with pytest.raises(ValueError, match="Hotine"):
        relief.write(tmp_path / "omerc.tif", a, transform=t, crs=omerc)
    with pytest.raises(ValueError, match="WKT 2"):
        relief.write(tmp_path / "wkt2.tif", a, transform=t, crs=omerc.to_wkt(version="WKT2_2019"))
    assert not (tmp_path / "omerc.tif").exists() and not (tmp_path / "wkt2.tif").exists()
