"""Reference outputs of RichDEM (and pysheds, when installed) for the landscape crate's flow
routing tests: the Rust side compares its results with these cell for cell.

Usage: python flow_reference.py IN.npy OUTDIR [--cell METRES]
IN.npy: a 2-D DEM (float32 or float64; row 0 = north). NaN cells are nodata: they are written
as -9999 (RichDEM's and pysheds' nodata value here) before anything runs. RichDEM computes in
the input's dtype (nextafter steps of the epsilon fill are float32 ulps for a float32 DEM).

Writes into OUTDIR (created when missing):
  fill_plain.npy       RichDEM FillDepressions(epsilon=False)  (Zhou 2016 priority flood, D8)
  fill_eps.npy         RichDEM FillDepressions(epsilon=True)   (Barnes 2014 Priority-Flood+eps)
  d8_acc_on_eps.npy    RichDEM FlowAccumulation(fill_eps, method='D8'), float64, in cells (own
                       cell included; edge cells receive but never pass flow; nodata = -1)
  d8_dir_on_eps.npy    int8 RichDEM D8 direction on fill_eps: 0 = no flow (edge, nodata, pit or
                       flat), else n = 1..8 with (dcol, drow) = W(-1,0) NW(-1,-1) N(0,-1)
                       NE(1,-1) E(1,0) SE(1,1) S(0,1) SW(-1,1)
  pysheds_fill.npy     pysheds fill_depressions (float32 input; pysheds' numba cache only
                       works for one dtype, see pysheds_notes.md)
  pysheds_inflated.npy pysheds resolve_flats(pysheds_fill) (float64, eps = 1e-5)
  pysheds_fdir.npy     pysheds flowdir(pysheds_inflated), int64, dirmap N=64 NE=128 E=1 SE=2
                       S=4 SW=8 W=16 NW=32, flat=-1, pit=-2, nodata=0 (cell size --cell)
  pysheds_acc.npy      pysheds accumulation(pysheds_fdir), float64, in cells
  meta.json            versions, shapes, dtypes and the time each step took
Prints meta.json's content on stdout.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "2")
os.environ.setdefault("NUMBA_NUM_THREADS", "2")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402

import numpy as np  # noqa: E402
from peer_common import stdout_to_stderr  # noqa: E402

NODATA = -9999.0


def timed(meta, key, fn):
    t0 = time.perf_counter()
    r = fn()
    meta["seconds"][key] = time.perf_counter() - t0
    return r


def richdem_outputs(dem, cell, out, meta):
    import richdem as rd
    from importlib.metadata import version

    meta["richdem_version"] = version("richdem2")

    def wrap(a):
        r = rd.rdarray(a, no_data=NODATA)
        r.geotransform = [0.0, cell, 0.0, 0.0, 0.0, -cell]
        return r

    with stdout_to_stderr():
        d = wrap(dem)
        plain = np.asarray(timed(meta, "richdem_fill_plain", lambda: rd.FillDepressions(d)))
        eps = np.asarray(
            timed(meta, "richdem_fill_eps", lambda: rd.FillDepressions(d, epsilon=True)))
        e = wrap(eps)
        acc = np.asarray(
            timed(meta, "richdem_d8_acc", lambda: rd.FlowAccumulation(e, method="D8")))
        props = np.asarray(rd.FlowProportions(e, method="D8"))
    if props.shape != dem.shape + (9,):
        raise RuntimeError(f"unexpected FlowProportions shape {props.shape}")
    dirs = np.where(props[..., 1:].max(axis=-1) > 0, props[..., 1:].argmax(axis=-1) + 1, 0)
    files = {
        "fill_plain.npy": plain.astype(dem.dtype),
        "fill_eps.npy": eps.astype(dem.dtype),
        "d8_acc_on_eps.npy": acc.astype(np.float64),
        "d8_dir_on_eps.npy": dirs.astype(np.int8),
    }
    for name, arr in files.items():
        np.save(os.path.join(out, name), np.ascontiguousarray(arr))
        meta["files"][name] = {"dtype": str(arr.dtype), "shape": list(arr.shape)}


def pysheds_outputs(dem, cell, out, meta):
    import pysheds
    from affine import Affine
    from pysheds.sgrid import sGrid
    from pysheds.sview import Raster, ViewFinder

    if not hasattr(np, "in1d"):  # removed in NumPy 2.4, still called by pysheds 0.5
        np.in1d = lambda a, b, **kw: np.isin(np.ravel(a), b, **kw)
    meta["pysheds_version"] = getattr(pysheds, "__version__", "?")
    a = dem.astype(np.float32)
    vf = ViewFinder(affine=Affine(cell, 0.0, 0.0, 0.0, -cell, 0.0), shape=a.shape,
                    nodata=np.float32(NODATA))
    r = Raster(a, viewfinder=vf)
    grid = sGrid.from_raster(r)
    filled = timed(meta, "pysheds_fill", lambda: grid.fill_depressions(r))
    inflated = timed(meta, "pysheds_resolve_flats", lambda: grid.resolve_flats(filled))
    fdir = timed(meta, "pysheds_flowdir", lambda: grid.flowdir(inflated))
    acc = timed(meta, "pysheds_accumulation", lambda: grid.accumulation(fdir))
    files = {
        "pysheds_fill.npy": np.asarray(filled),
        "pysheds_inflated.npy": np.asarray(inflated, dtype=np.float64),
        "pysheds_fdir.npy": np.asarray(fdir, dtype=np.int64),
        "pysheds_acc.npy": np.asarray(acc, dtype=np.float64),
    }
    for name, arr in files.items():
        np.save(os.path.join(out, name), np.ascontiguousarray(arr))
        meta["files"][name] = {"dtype": str(arr.dtype), "shape": list(arr.shape)}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("input")
    p.add_argument("outdir")
    p.add_argument("--cell", type=float, default=1.0,
                   help="cell size in metres (pysheds' steepest-descent distances only)")
    a = p.parse_args()
    dem = np.load(a.input)
    if dem.ndim != 2:
        sys.exit("input must be a 2-D array")
    if dem.dtype not in (np.float32, np.float64):
        dem = dem.astype(np.float64)
    dem = np.ascontiguousarray(dem).copy()
    nan = ~np.isfinite(dem)
    dem[nan] = NODATA
    os.makedirs(a.outdir, exist_ok=True)
    meta = {"input": a.input, "shape": list(dem.shape), "dtype": str(dem.dtype),
            "nodata_cells": int(nan.sum()), "nodata": NODATA, "cell": a.cell,
            "seconds": {}, "files": {}, "skipped": {}}
    t0 = time.perf_counter()
    for name, fn in (("richdem", richdem_outputs), ("pysheds", pysheds_outputs)):
        try:
            fn(dem, a.cell, a.outdir, meta)
        except ImportError as e:
            meta["skipped"][name] = f"not installed: {e}"
        except Exception as e:  # noqa: BLE001
            traceback.print_exc()
            meta["skipped"][name] = f"failed: {e}"
    meta["seconds"]["total"] = time.perf_counter() - t0
    with open(os.path.join(a.outdir, "meta.json"), "w") as f:
        json.dump(meta, f, indent=1)
    json.dump(meta, sys.stdout, indent=1)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
