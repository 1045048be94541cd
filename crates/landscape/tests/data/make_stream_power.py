"""Makes the fastscapelib references of relief-landscape's stream-power one-step tests.

Run once from /work/main with fastscapelib 0.3.0 (target/peers-venv):
    target/peers-venv/bin/python crates/landscape/tests/data/make_stream_power.py
The step is the one of xtask/peers/stream_power.py (fastscapelib's "Mountain" loop) on a
non-square raster (RasterGrid spacing [dy, dx] = [80, 100] m): uplift of the interior, D8 +
MST sink resolver (a no-op here: the input is pit-free, checked below), accumulate(1.0),
SPLEroder(tolerance=1e-5), DiffusionADIEroder. Regenerating is legitimate only when the
model itself changes (a new fastscapelib step definition), never to make a test pass.
"""

import json
import os

import numpy as np

import fastscapelib as fs

HERE = os.path.dirname(os.path.abspath(__file__))
NR, NC, DY, DX = 48, 64, 80.0, 100.0
CASES = {  # name: (k, m, n, kd, dt, uplift, with diffusion)
    "spl_n1": (2e-4, 0.4, 1.0, 0.0, 1e3, 1e-3, False),
    "spl_n1_kd001": (2e-4, 0.4, 1.0, 0.01, 1e3, 1e-3, True),
    "spl_n1_kd2": (2e-4, 0.4, 1.0, 2.0, 1e3, 1e-3, True),
    "spl_n15_kd001": (2e-4, 0.4, 1.5, 0.01, 1e3, 1e-3, True),
}


def surface():
    """A smooth uplifted block (a dome on a 1.5 m per cell pyramid) with 0.5 m of noise: every
    interior node has a strictly lower neighbour toward its nearest edge (pit-free)."""
    rng = np.random.Generator(np.random.PCG64(20240601))
    r, c = np.mgrid[0:NR, 0:NC].astype(np.float64)
    border = np.minimum(np.minimum(r, NR - 1 - r), np.minimum(c, NC - 1 - c))
    dome = np.sin(np.pi * r / (NR - 1)) * np.sin(np.pi * c / (NC - 1))
    return 50.0 + 1.5 * border + 20.0 * dome + rng.uniform(0.0, 0.5, size=(NR, NC))


def one_step(z, k, m, n, kd, dt, u, with_diffusion):
    grid = fs.RasterGrid([NR, NC], [DY, DX], fs.NodeStatus.FIXED_VALUE)
    graph = fs.FlowGraph(grid, [fs.SingleFlowRouter(), fs.MSTSinkResolver()])
    spl = fs.SPLEroder(graph, k_coef=k, area_exp=m, slope_exp=n, tolerance=1e-5)
    uplift = np.full(z.shape, u)
    uplift[[0, -1], :] = 0.0
    uplift[:, [0, -1]] = 0.0
    uplifted = z + dt * uplift
    plain = fs.FlowGraph(grid, [fs.SingleFlowRouter()])
    plain.update_routes(uplifted)
    rec = np.asarray(plain.impl().receivers)[:, 0]
    own = (rec == np.arange(z.size)).reshape(z.shape)
    assert own[1:-1, 1:-1].sum() == 0, "the input must be pit-free"
    graph.update_routes(uplifted)
    area = np.empty_like(z)
    graph.accumulate(area, 1.0)
    e_spl = spl.erode(uplifted, area, dt)
    if not with_diffusion:
        return uplifted - e_spl, int(spl.n_corr)
    e_dif = fs.DiffusionADIEroder(grid, kd).erode(uplifted - e_spl, dt)
    return uplifted - e_spl - e_dif, int(spl.n_corr)


def main():
    z = surface()
    np.save(os.path.join(HERE, "spl_in.npy"), z)
    summary = {"fastscapelib": fs.__version__}
    for name, case in CASES.items():
        out, n_corr = one_step(z, *case)
        np.save(os.path.join(HERE, f"{name}.npy"), np.ascontiguousarray(out))
        summary[name] = {"n_corr": n_corr, "max_dz": float(np.abs(out - z).max())}
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
