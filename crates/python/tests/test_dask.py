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


def _basin(w: int = 96, h: int = 90) -> np.ndarray:
    """A bowl over the middle 3 x 3 tiles of 32 cells (filled to a lake over nine tiles), a
    river winding across every tile edge, integer elevations (flats) and a few voids."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    u = np.random.default_rng(5).random((h, w))
    r = np.hypot((x - w / 2) / w, (y - h / 2) / h)
    bowl = np.where(r < 0.3, 10 + 60 * r, 28 + (r - 0.3) * 120)
    path = h * (0.5 + 0.42 * np.sin(x / w * 9))
    river = np.maximum(np.abs(y - path) - 2, 0) * 3 + x * 0.05
    z = np.where(r < 0.3, bowl, np.where(np.abs(y - path) < 3, river, np.minimum(bowl, river + 6)))
    z = np.floor(z + u * 2)
    z[u < 0.005] = np.nan
    return z.astype(np.float32)


def _flow_equal(lazy: dict, single: dict, client=None) -> None:
    import dask

    keys = ("conditioned", "direction", "area", "strahler", "watersheds", "hand")
    if client is None:
        out = dask.compute(lazy)[0]
    else:
        futures = client.compute(list(lazy.values()))
        out = dict(zip(list(lazy), client.gather(futures)))
    for k in keys:
        assert same_bits(np.asarray(out[k]), single[k]), k
    assert out["channels"] == single["channels"]
    assert len(out["channels"]["features"]) > 4


def test_flow_on_two_worker_processes_equals_the_single_run(client):
    dem = _basin()
    single = relief.flow(dem, cell_size=(30, 20), channel_area=30 * 20 * 12)
    for tile in (32, 16, 45):
        lazy = rdask.flow(dem, tile=tile, cell_size=(30, 20), channel_area=30 * 20 * 12)
        assert lazy["area"].numblocks == (-(-90 // tile), -(-96 // tile))
        _flow_equal(lazy, single, client if tile == 32 else None)
    # A dask array stays lazy: each tile's task reads its own slice.
    lazy = rdask.flow(da.from_array(dem, chunks=40), tile=32, cell_size=(30, 20), channel_area=7200)
    _flow_equal(lazy, single)
    # The graph: per-tile tasks of phases 1, 3, 5, 7, one task of phases 2, 4, 6.
    graph = dict(lazy["hand"].__dask_graph__())
    for phase, count in ((1, 9), (2, 1), (3, 9), (4, 1), (5, 9), (6, 1), (7, 9)):
        names = [k for k in graph if (k[0] if isinstance(k, tuple) else k).startswith(f"relief-flow-phase{phase}-")]
        assert len(names) == count, (phase, names)
    # Each phase is one named layer of the high-level graph, holding every task of the phase.
    layers = lazy["hand"].__dask_graph__().layers
    for phase, count in ((1, 9), (2, 1), (3, 9), (4, 1), (5, 9), (6, 1), (7, 9)):
        [name] = [k for k in layers if str(k).startswith(f"relief-flow-phase{phase}-")]
        assert len(layers[name]) == count, (phase, name)


def test_flow_of_a_real_dem_crop_equals_the_single_run():
    r = relief.read(FIXTURE)
    single = relief.flow(r, channel_area=2e5)
    lazy = rdask.flow(r, tile=64, channel_area=2e5)
    _flow_equal(lazy, single)


def test_flow_refuses_what_has_no_tiled_form():
    dem = _basin()
    for bad, what in (({"depressions": "breach"}, "depressions"), ({"directions": "mfd"}, "directions"),
                      ({"channel_area": -1.0}, "channel_area"), ({"lakes": 1}, "lakes")):
        with pytest.raises(ValueError, match=what):
            rdask.flow(dem, cell_size=30, **bad)


def _masks_equal(lazy: dict, single: dict, client=None) -> None:
    import dask

    if client is None:
        out = dask.compute(lazy)[0]
    else:
        futures = client.compute(list(lazy.values()))
        out = dict(zip(list(lazy), client.gather(futures)))
    for k in ("slope", "profile_curvature", "plan_curvature", "area", "wetness", "hand", "height_band", "splat"):
        assert same_bits(np.asarray(out[k]), single[k]), k
    assert len(out["scales"]["bands"]) == 3


def test_masks_on_two_worker_processes_equals_the_single_run(client):
    dem = _basin()
    single = relief.masks(dem, cell_size=(30, 20), flow={"channel_area": 7200})
    lazy = rdask.masks(dem, tile=32, cell_size=(30, 20), flow={"channel_area": 7200})
    assert lazy["splat"].shape == (90, 96, 4)
    _masks_equal(lazy, single, client)
    lazy = rdask.masks(da.from_array(dem, chunks=40), tile=45, cell_size=(30, 20), flow={"channel_area": 7200})
    _masks_equal(lazy, single)
    given = relief.masks(dem, cell_size=30, height_bands=[20.0, 40.0], rock_slope=25.0)
    lazy = rdask.masks(dem, tile=16, cell_size=30, height_bands=[20.0, 40.0], rock_slope=25.0)
    out = lazy["height_band"].compute()
    assert same_bits(out, given["height_band"]) and np.nanmax(out) == 2


def test_masks_of_a_real_dem_crop_equals_the_single_run():
    r = relief.read(FIXTURE)
    _masks_equal(rdask.masks(r, tile=64), relief.masks(r))


def test_masks_refuse_what_has_no_tiled_form():
    dem = _basin()
    for bad, what in (({"flow": {"directions": "mfd"}}, "directions"), ({"rock_slope": 95.0}, "rock_slope"),
                      ({"erosion": 1}, "erosion")):
        with pytest.raises(ValueError, match=what):
            rdask.masks(dem, cell_size=30, **bad)
