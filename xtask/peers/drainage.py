"""RichDEM and pysheds peers of the landscape crate's flow routing benchmark (depression filling
+ D8 flow accumulation on a 4096^2 DEM).

Usage: python drainage.py DATA_DIR [REPEATS]
Reads DATA_DIR/flow_4096.npy (float32 DEM, 4096 x 4096, row 0 = north, 30 m cells). When the
file is missing, prints {} and exits 0. Each peer is timed on the same array (one small warm-up
so that numba's compilation is not timed, then the median of REPEATS runs, default 3):

- richdem (the `richdem2` wheel, a maintained build of RichDEM; the original `richdem` 0.3.4 on
  PyPI does not build on CPython 3.11): `rd.FillDepressions(dem, epsilon=True)` (Priority-Flood
  +epsilon, Barnes 2014) then `rd.FlowAccumulation(filled, method='D8')` (O'Callaghan D8:
  flow to the lowest neighbour, edge cells are outlets, output in cells).
- pysheds: `grid.fill_depressions` -> `grid.resolve_flats` -> `grid.flowdir` (D8, steepest
  slope with 30 m cells) -> `grid.accumulation`, on an in-memory `pysheds.sview.Raster` with a
  `ViewFinder` (no file I/O).

Threads: OMP_NUM_THREADS=2 (RichDEM's flow directions use OpenMP) and NUMBA_NUM_THREADS=2
(pysheds' numba kernels), unless already set.

Prints one JSON object on stdout: "richdem_fill_d8_4096_s" and "pysheds_fill_d8_4096_s" (the
dashboard's peer times: fill + directions + accumulation), their parts
("richdem_fill_d8_4096_fill_s", "..._acc_s", "pysheds_fill_d8_4096_fill_s", "..._flats_s",
"..._fdir_s", "..._acc_s"), the outlet accumulation maxima ("..._max_acc_cells") and the
versions. A peer whose package is not installed (or that fails) is left out; its error goes to
stderr.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "2")
os.environ.setdefault("NUMBA_NUM_THREADS", "2")

import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402

import numpy as np  # noqa: E402
from peer_common import load_input, stdout_to_stderr  # noqa: E402

CELL = 30.0
NODATA = -9999.0
SIZE = 4096


def median_runs(fn, repeats):
    """Runs `fn` (returning a dict of part times and a result) REPEATS times; returns the
    median total, the median of each part and the last result."""
    totals, parts, result = [], {}, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        p, result = fn()
        totals.append(time.perf_counter() - t0)
        for k, v in p.items():
            parts.setdefault(k, []).append(v)
    return float(np.median(totals)), {k: float(np.median(v)) for k, v in parts.items()}, result


def time_peer(prepare, run, dem, repeats, key):
    """Times `run` (returning a dict of part times and the accumulation) on `prepare(dem)`
    after one small warm-up (so that numba's compilation is not timed): the median total
    `{key}_s`, each part `{key}_{part}_s` and the largest accumulation."""
    run(prepare(dem[:256, :256].copy()))
    r = prepare(dem)
    total, parts, acc = median_runs(lambda: run(r), repeats)
    out = {f"{key}_s": total}
    out.update({f"{key}_{part}_s": t for part, t in parts.items()})
    out[f"{key}_max_acc_cells"] = float(np.asarray(acc).max())
    return out


def richdem_peer(dem, repeats):
    import richdem as rd

    try:
        from importlib.metadata import version

        ver = version("richdem2")
    except Exception:  # noqa: BLE001
        ver = getattr(rd, "__version__", "?")

    def prepare(a):
        r = rd.rdarray(a, no_data=NODATA)
        r.geotransform = [0.0, CELL, 0.0, 0.0, 0.0, -CELL]
        return r

    def run(a):
        t0 = time.perf_counter()
        filled = rd.FillDepressions(a, epsilon=True)
        t1 = time.perf_counter()
        acc = rd.FlowAccumulation(filled, method="D8")
        t2 = time.perf_counter()
        return {"fill": t1 - t0, "acc": t2 - t1}, acc

    with stdout_to_stderr():
        out = time_peer(prepare, run, dem, repeats, f"richdem_fill_d8_{dem.shape[0]}")
    return {**out, "richdem_version": ver}


def pysheds_peer(dem, repeats):
    import pysheds
    from affine import Affine
    from pysheds.sgrid import sGrid
    from pysheds.sview import Raster, ViewFinder

    if not hasattr(np, "in1d"):
        # pysheds 0.5's D8 accumulation calls np.in1d, removed in NumPy 2.4; np.isin on the
        # flattened array is the same function.
        np.in1d = lambda a, b, **kw: np.isin(np.ravel(a), b, **kw)

    def prepare(a):
        vf = ViewFinder(affine=Affine(CELL, 0.0, 0.0, 0.0, -CELL, 0.0), shape=a.shape,
                        nodata=np.float32(NODATA))
        return Raster(a, viewfinder=vf)

    def run(r):
        grid = sGrid.from_raster(r)
        t0 = time.perf_counter()
        flooded = grid.fill_depressions(r)
        t1 = time.perf_counter()
        inflated = grid.resolve_flats(flooded)
        t2 = time.perf_counter()
        fdir = grid.flowdir(inflated)
        t3 = time.perf_counter()
        acc = grid.accumulation(fdir)
        t4 = time.perf_counter()
        return {"fill": t1 - t0, "flats": t2 - t1, "fdir": t3 - t2, "acc": t4 - t3}, acc

    out = time_peer(prepare, run, dem, repeats, f"pysheds_fill_d8_{dem.shape[0]}")
    return {**out, "pysheds_version": pysheds.__version__ if hasattr(pysheds, "__version__") else "?"}


def main():
    data = sys.argv[1]
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    dem = load_input("drainage.py", os.path.join(data, f"flow_{SIZE}.npy"), np.float32)
    if dem is None:
        return
    dem[~np.isfinite(dem)] = NODATA
    out = {}
    for name, peer in (("richdem", richdem_peer), ("pysheds", pysheds_peer)):
        try:
            out.update(peer(dem, repeats))
        except ImportError as e:
            print(f"drainage.py: {name} not installed ({e}), skipped", file=sys.stderr)
        except Exception:  # noqa: BLE001
            print(f"drainage.py: {name} failed, skipped", file=sys.stderr)
            traceback.print_exc()
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
