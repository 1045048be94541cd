"""Errors as Python exceptions: ValueError with the library's message for bad parameters and
inputs, OSError for files."""

from __future__ import annotations

import numpy as np
import pytest

import relief
from conftest import FIXTURE

COARSE = np.linspace(0, 300, 24 * 24, dtype=np.float32).reshape(24, 24)


def test_library_check_messages():
    with pytest.raises(ValueError, match=r"invalid parameter `radius` = 0.5: must be in \[1, 32\] coarse pixels"):
        relief.amplify(COARSE, FIXTURE, 4, cell_size=30, radius=0.5)
    with pytest.raises(ValueError, match=r"invalid parameter `sparsity` = 0: must be in 1..=64"):
        relief.amplify(COARSE, FIXTURE, 4, cell_size=30, sparsity=0)
    with pytest.raises(ValueError, match=r"channel_area"):
        relief.flow(COARSE, cell_size=30, channel_area=-1.0)


def test_unknown_and_mistyped_settings():
    with pytest.raises(ValueError, match=r"unknown field `radiuss`"):
        relief.amplify(COARSE, FIXTURE, 4, cell_size=30, radiuss=4)
    with pytest.raises(ValueError, match=r"invalid type"):
        relief.refine(COARSE, cell_size=30, seed="one")
    with pytest.raises(ValueError, match=r"unknown variant `bilinear`"):
        relief.amplify(COARSE, FIXTURE, 4, cell_size=30, residual_kernel="bilinear")


def test_factor_and_cell_size():
    with pytest.raises(ValueError, match=r"invalid factor 8: must be a power of 4"):
        relief.amplify(COARSE, FIXTURE, 8, cell_size=30)
    with pytest.raises(ValueError, match=r"invalid cell size 0 x 0 m"):
        relief.amplify(COARSE, FIXTURE, 4, cell_size=0)
    with pytest.raises(ValueError, match=r"has no cell size"):
        relief.amplify(COARSE, FIXTURE, 4)


def test_voids_are_refused():
    a = COARSE.copy()
    a[3, 4] = np.nan
    with pytest.raises(ValueError, match=r"cannot use the coarse input: heightfield has 1 void"):
        relief.amplify(a, FIXTURE, 4, cell_size=30)


def test_files():
    with pytest.raises(OSError, match=r"no/such/dem.tif"):
        relief.read("/no/such/dem.tif")
    with pytest.raises(OSError):
        relief.write("/no/such/dir/out.tif", COARSE, cell_size=30)
    with pytest.raises(ValueError, match=r"cannot choose an output format"):
        relief.write("/tmp/out.unknown", COARSE, cell_size=30)
    with pytest.raises(OSError):
        relief.amplify(COARSE, "/no/such/exemplar.tif", 4, cell_size=30)


def test_bad_window():
    with pytest.raises(ValueError, match=r"window"):
        relief.amplify(COARSE, FIXTURE, 4, cell_size=30, window=(90, 0, 20, 20), landform=False)
