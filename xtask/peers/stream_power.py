"""fastscapelib peer of the landscape crate's stream-power + hillslope diffusion benchmark, and a
reference for the crate's one-step tests.

Model (fastscapelib 0.3, the loop of its "Mountain" example notebook):
  grid      RasterGrid(shape, [dx, dx], NodeStatus.FIXED_VALUE): all 4 edges are base levels
  graph     FlowGraph(grid, [SingleFlowRouter(), MSTSinkResolver()])  (MST: Kruskal, carve)
  channel   SPLEroder(graph, k_coef=K, area_exp=m, slope_exp=n, tolerance=1e-5)
  hillslope DiffusionADIEroder(grid, KD)
  one step  uplifted = z + dt * U              (U = uplift on interior nodes, 0 on the edges)
            graph.update_routes(uplifted)      (D8 steepest descent, then MST re-routing of pits;
                                                the filled elevation it returns is NOT used)
            A = graph.accumulate(1.0)          (drainage area in m^2, own cell included)
            e_spl = spl.erode(uplifted, A, dt)
            e_dif = diffusion.erode(uplifted - e_spl, dt)
            z = uplifted - e_spl - e_dif
Defaults: dx = 100 m, dt = 1e3 yr, U = 1e-3 m/yr, K = 2e-4 (m^(1-2m)/yr, the value of
fastscapelib's Mountain example), m = 0.4, n = 1, KD = 0.01 m^2/yr. See
target/fastscapelib_notes.md for the exact formulas.

Usage:
  python stream_power.py DATA_DIR [STEPS]
      Reads DATA_DIR/spl_1024.npy (float64 1024 x 1024 initial elevation, 100 m cells; prints {}
      when missing), runs STEPS steps (default 100) and prints
      {"fastscapelib_spl_diffusion_step_1024_s": median seconds per step, ...}.
  python stream_power.py --one-step IN.npy OUT.npy [options]
      One step as above; saves the new elevation (float64, same shape) to OUT.npy.
  python stream_power.py --one-step-spl-only IN.npy OUT.npy [options]
      Same without the diffusion: OUT = uplifted - e_spl.
  python stream_power.py --receivers IN.npy OUT.npy [options]
      Routes the uplifted IN (the graph the one step uses) and saves the receivers (flat
      row-major indices, int64, shape of IN; a node that is its own receiver is a base level or
      an unresolved pit) to OUT.npy and the drainage area (float64, m^2) to OUT_area.npy
      (OUT's name without .npy, plus _area.npy), and the receiver distances (float64, m) to
      OUT_dist.npy.
  Options: --dx 100 --dt 1e3 --uplift 1e-3 --k 2e-4 --m 0.4 --n 1 --kd 0.01 --no-sink-resolver
  (--uplift 0 routes IN itself). The one-step modes print a JSON summary on stdout: the number
  of interior pits of the plain D8 graph (0 = the MST sink resolver changed nothing) and the
  SPL eroder's n_corr (nodes whose erosion was limited).
"""

import argparse
import json
import os
import sys
import time

import numpy as np
from peer_common import load_input

try:
    import fastscapelib as fs
except ImportError as _e:  # an older peers venv: no timing rather than a failed peer
    fs = None
    _FS_ERROR = _e

SIZE = 1024


def build(shape, a):
    grid = fs.RasterGrid(list(shape), [a.dx, a.dx], fs.NodeStatus.FIXED_VALUE)
    ops = [fs.SingleFlowRouter()]
    if not a.no_sink_resolver:
        ops.append(fs.MSTSinkResolver())
    graph = fs.FlowGraph(grid, ops)
    spl = fs.SPLEroder(graph, k_coef=a.k, area_exp=a.m, slope_exp=a.n, tolerance=1e-5)
    diffusion = fs.DiffusionADIEroder(grid, a.kd)
    uplift = np.full(shape, a.uplift, dtype=np.float64)
    uplift[[0, -1], :] = 0.0
    uplift[:, [0, -1]] = 0.0
    return grid, graph, spl, diffusion, uplift


def step(z, graph, spl, diffusion, uplift, area, dt, with_diffusion=True):
    uplifted = z + dt * uplift
    graph.update_routes(uplifted)
    graph.accumulate(area, 1.0)
    e_spl = spl.erode(uplifted, area, dt)
    if not with_diffusion:
        return uplifted - e_spl
    e_dif = diffusion.erode(uplifted - e_spl, dt)
    return uplifted - e_spl - e_dif


def interior_pits(z, dx):
    """Interior nodes that are their own D8 receiver (before any sink resolution)."""
    grid = fs.RasterGrid(list(z.shape), [dx, dx], fs.NodeStatus.FIXED_VALUE)
    g = fs.FlowGraph(grid, [fs.SingleFlowRouter()])
    g.update_routes(z)
    rec = np.asarray(g.impl().receivers)[:, 0].reshape(z.shape).astype(np.int64)
    own = rec == np.arange(z.size, dtype=np.int64).reshape(z.shape)
    return int(own[1:-1, 1:-1].sum())


def bench(data, steps, a):
    if fs is None:
        print(f"stream_power.py: fastscapelib not installed ({_FS_ERROR})", file=sys.stderr)
        print("{}")
        return
    z = load_input("stream_power.py", os.path.join(data, f"spl_{SIZE}.npy"), np.float64)
    if z is None:
        return
    # keep `grid` referenced: the flow graph and the eroders hold it by reference only
    grid, graph, spl, diffusion, uplift = build(z.shape, a)
    area = np.empty_like(z)
    times = []
    for _ in range(steps):
        t0 = time.perf_counter()
        z = step(z, graph, spl, diffusion, uplift, area, a.dt)
        times.append(time.perf_counter() - t0)
    key = f"fastscapelib_spl_diffusion_step_{z.shape[0]}"
    out = {
        f"{key}_s": float(np.median(times)),
        f"{key}_total_s": float(np.sum(times)),
        f"{key}_steps": steps,
        f"{key}_final_mean_elev_m": float(z.mean()),
        f"{key}_final_max_elev_m": float(z.max()),
        "fastscapelib_version": fs.__version__,
    }
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")


def one_step(mode, inp, outp, a):
    if fs is None:
        sys.exit(f"fastscapelib not installed ({_FS_ERROR})")
    z = np.ascontiguousarray(np.load(inp), dtype=np.float64)
    if z.ndim != 2:
        sys.exit("input must be a 2-D array")
    grid, graph, spl, diffusion, uplift = build(z.shape, a)  # noqa: F841 (kept alive)
    area = np.empty_like(z)
    summary = {"pits_before_sink_resolver": interior_pits(z + a.dt * uplift, a.dx)}
    if summary["pits_before_sink_resolver"] and not a.no_sink_resolver:
        print(
            f"stream_power.py: {summary['pits_before_sink_resolver']} interior pits: the MST "
            "sink resolver re-routes them (see fastscapelib_notes.md)",
            file=sys.stderr,
        )
    if mode == "receivers":
        uplifted = z + a.dt * uplift
        graph.update_routes(uplifted)
        graph.accumulate(area, 1.0)
        impl = graph.impl()
        rec = np.asarray(impl.receivers)[:, 0].astype(np.int64).reshape(z.shape)
        dist = np.asarray(impl.receivers_distance)[:, 0].astype(np.float64).reshape(z.shape)
        stem = outp[:-4] if outp.endswith(".npy") else outp
        np.save(outp, rec)
        np.save(stem + "_area.npy", area.astype(np.float64))
        np.save(stem + "_dist.npy", dist)
        summary["outputs"] = [outp, stem + "_area.npy", stem + "_dist.npy"]
    else:
        out = step(z, graph, spl, diffusion, uplift, area, a.dt, mode == "one-step")
        np.save(outp, np.ascontiguousarray(out, dtype=np.float64))
        summary["n_corr"] = int(spl.n_corr)
        summary["outputs"] = [outp]
    summary["params"] = {
        "dx": a.dx, "dt": a.dt, "uplift": a.uplift, "k": a.k, "m": a.m, "n": a.n, "kd": a.kd,
        "sink_resolver": None if a.no_sink_resolver else "mst_kruskal_carve",
    }
    json.dump(summary, sys.stdout)
    sys.stdout.write("\n")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    g = p.add_mutually_exclusive_group()
    g.add_argument("--one-step", nargs=2, metavar=("IN", "OUT"))
    g.add_argument("--one-step-spl-only", nargs=2, metavar=("IN", "OUT"))
    g.add_argument("--receivers", nargs=2, metavar=("IN", "OUT"))
    p.add_argument("data", nargs="?")
    p.add_argument("steps", nargs="?", type=int, default=100)
    p.add_argument("--dx", type=float, default=100.0)
    p.add_argument("--dt", type=float, default=1e3)
    p.add_argument("--uplift", type=float, default=1e-3)
    p.add_argument("--k", type=float, default=2e-4)
    p.add_argument("--m", type=float, default=0.4)
    p.add_argument("--n", type=float, default=1.0)
    p.add_argument("--kd", type=float, default=0.01)
    p.add_argument("--no-sink-resolver", action="store_true")
    a = p.parse_args()
    if a.one_step:
        one_step("one-step", *a.one_step, a)
    elif a.one_step_spl_only:
        one_step("spl-only", *a.one_step_spl_only, a)
    elif a.receivers:
        one_step("receivers", *a.receivers, a)
    elif a.data:
        bench(a.data, a.steps, a)
    else:
        p.error("DATA_DIR or one of --one-step, --one-step-spl-only, --receivers is required")


if __name__ == "__main__":
    main()
