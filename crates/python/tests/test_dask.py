"""relief.dask: chunks as exact windows, on a distributed LocalCluster of 2 worker processes,
equal to the single in-memory run bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

import relief
from conftest import FIXTURE

da = pytest.importorskip("dask.array")
distributed = pytest.importorskip("distributed")
import relief.dask as rdask  # noqa: E402

rng = np.random.default_rng(11)
COARSE = (np.cumsum(np.cumsum(rng.normal(size=(40, 52)), 0), 1) * 4 + 900).astype(np.float32)


def same_bits(a, b):
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


def computed(client, x):
    """x computed on the cluster, failing (not hanging) when it cannot finish."""
    return client.compute(x).result(timeout=240)


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        with distributed.Client(cluster) as c:
            yield c


def test_amplify_on_two_worker_processes_equals_the_single_run(client):
    single = relief.amplify(COARSE, FIXTURE, 16, cell_size=60, seed=4, landform=False)
    lazy = rdask.amplify(da.from_array(COARSE, chunks=20), FIXTURE, 16, cell_size=60, seed=4,
                         chunks=(250, 300))
    assert lazy.shape == single.shape and lazy.numblocks == (3, 3)
    out = computed(client, lazy)
    # Every window was computed on a worker process (not here).
    assert len(client.scheduler_info()["workers"]) == 2
    assert same_bits(out, single)


def test_refine_on_two_worker_processes_equals_the_single_run(client):
    single = relief.refine(COARSE, cell_size=60, extra_levels=3, seed=9, landform=False)
    out = rdask.refine(COARSE, cell_size=60, extra_levels=3, seed=9, chunks=(128, 160))
    out = computed(client, out)
    assert same_bits(out, single)


def test_dask_backed_xarray_keeps_coordinates(client):
    xr = pytest.importorskip("xarray")
    x = 500000.0 + 60.0 * (np.arange(52) + 0.5)
    y = 4000000.0 - 60.0 * (np.arange(40) + 0.5)
    arr = xr.DataArray(COARSE, dims=("y", "x"), coords={"x": x, "y": y}).chunk(20)
    out = arr.relief.amplify(FIXTURE, 4, seed=4, chunks=64)
    assert out.chunks is not None
    single = relief.amplify(COARSE, FIXTURE, 4, cell_size=60, seed=4, landform=False)
    assert same_bits(computed(client, out.data), single)
    assert out.x.values[0] == pytest.approx(500000.0 + 7.5)
    assert out.y.values[-1] == pytest.approx(4000000.0 - 60 * 40 + 7.5)


def test_the_landform_pass_has_no_windows():
    with pytest.raises(ValueError, match="landform pass routes water over the whole raster"):
        rdask.amplify(COARSE, FIXTURE, 4, cell_size=60, landform=True)
    # Off is what relief.dask computes anyway.
    assert rdask.refine(COARSE, cell_size=60, landform=False, chunks=64).shape == (160, 208)


def test_plans_pickle_and_unaligned_arrays_are_read():
    import pickle

    from relief import _relief

    buf = np.zeros(COARSE.size * 4 + 1, np.uint8)
    unaligned = buf[1:].view(np.float32).reshape(COARSE.shape)
    unaligned[...] = COARSE
    assert not unaligned.flags.aligned
    single = relief.refine(COARSE, cell_size=60, extra_levels=2, seed=9, landform=False)
    assert same_bits(relief.refine(unaligned, cell_size=60, extra_levels=2, seed=9, landform=False), single)
    plan = _relief.refine_plan(COARSE, (60.0, 60.0), (None, None, None), '{"extra_levels": 2, "seed": 9}', False)
    again = pickle.loads(pickle.dumps(plan, protocol=5))
    assert same_bits(again.window(30, 20, 50, 40), single[20:60, 30:80])
