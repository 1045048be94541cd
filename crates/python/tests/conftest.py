"""Shared fixtures of the relief Python tests: the repository's fixture DEM, the shared DEMs
(../shared/data/dem, skipped with a notice when absent, failing under CI=true), the `relief`
binary cargo built (target/debug/relief) and a small georeferenced crop."""

from __future__ import annotations

import os
import pathlib
import shutil

import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]
FIXTURE = REPO / "fixtures" / "grandcanyon.tif"
SHARED = REPO.parent / "shared" / "data" / "dem"
CI = os.environ.get("CI") == "true"


def need(ok: bool, why: str) -> None:
    """Skips with a notice when `ok` is false, or fails under CI=true."""
    if ok:
        return
    if CI:
        pytest.fail(f"{why} (required under CI=true)")
    print(f"notice: skipped: {why}")
    pytest.skip(why)


@pytest.fixture(scope="session")
def relief_bin() -> pathlib.Path:
    """The `relief` binary of `cargo build` (target/debug/relief, or $RELIEF_BIN)."""
    p = pathlib.Path(os.environ.get("RELIEF_BIN", REPO / "target" / "debug" / "relief"))
    need(p.exists() or shutil.which(str(p)) is not None, f"no relief binary at {p} (cargo build -p relief-cli)")
    return p


@pytest.fixture(scope="session")
def shared_dem() -> pathlib.Path:
    """The shared alps DEM (GeoTIFF), original bytes."""
    p = SHARED / "alps_dem.tiff"
    need(p.exists(), f"the shared DEM {p} is absent")
    return p


@pytest.fixture(scope="session")
def shared_srtm() -> pathlib.Path:
    """The shared SRTM tile N47E011 (EPSG:4326)."""
    p = SHARED / "N47E011.hgt"
    need(p.exists(), f"the shared DEM {p} is absent")
    return p


@pytest.fixture(scope="session")
def crop(tmp_path_factory: pytest.TempPathFactory) -> pathlib.Path:
    """A 40 x 32 GeoTIFF crop of grandcanyon (EPSG:3857), written by rasterio with its window
    transform."""
    rasterio = pytest.importorskip("rasterio")
    from rasterio.windows import Window, transform as wtransform

    out = tmp_path_factory.mktemp("crop") / "crop.tif"
    with rasterio.open(FIXTURE) as src:
        w = Window(200, 240, 40, 32)
        a = src.read(1, window=w).astype("float32")
        profile = dict(
            driver="GTiff", width=40, height=32, count=1, dtype="float32",
            crs=src.crs, transform=wtransform(w, src.transform),
        )
    with rasterio.open(out, "w", **profile) as dst:
        dst.write(a, 1)
    return out
