"""Reference outputs of the peers for relief-landscape's exactness tests.

Usage: python landscape_reference.py DEM.npy CELL_X_M CELL_Y_M OUTDIR
Writes into OUTDIR (float64 .npy, C order; the DEM itself stays in ../shared):
  rd_fill_raised.npy      RichDEM FillDepressions(epsilon=False): the cells it raises, rows of
                          (cell index, filled elevation)
  rd_fill_eps_raised.npy  the same for FillDepressions(epsilon=True)
  fs_area.npy      fastscapelib FlowGraph([SingleFlowRouter()]) drainage area (m^2, float64)
                   on rd_fill_eps (a surface on which every interior cell drains), all four
                   edges fixed-value (outlets)
  ps_receiver.npy  pysheds (sGrid.flowdir, routing='d8') on rd_fill_eps: each cell's receiver
                   index, -1 for none; pysheds also gives the edge cells directions into the
                   map, which are dropped here (edges are outlets, as in RichDEM, fastscapelib
                   and relief)
  ps_area.npy      pysheds sGrid.accumulation of those directions times the cell area (m^2)
The committed copies under crates/landscape/tests/data/ were made with richdem2 2.4.3,
fastscapelib 0.3.0 and pysheds 0.5 (whose `accumulation` calls `np.in1d`, gone from numpy 2:
the script restores it as `np.isin`) (`cargo xtask bench`'s peers venv) from jacksboro_fault rows 64..192,
columns 192..320 (`shared/data/dem/jacksboro_fault.f32`, 74.573 m x 92.475 m cells: non-square,
1,332 cells in closed depressions; matplotlib's sample data `jacksboro_fault_dem.npz`,
Matplotlib License).
"""
import os
import sys

import numpy as np


def pysheds_d8(z, cell_x, cell_y):
    """pysheds' D8 receivers (cell index, -1 for none) and drainage area (m^2) on `z`."""
    if not hasattr(np, "in1d"):
        np.in1d = np.isin
    from affine import Affine
    from pysheds.sgrid import sGrid
    from pysheds.view import Raster, ViewFinder
    vf = ViewFinder(affine=Affine(cell_x, 0, 0, 0, -cell_y, 0), shape=z.shape,
                    nodata=np.float64(-9999.0))
    grid = sGrid(viewfinder=vf)
    fdir = grid.flowdir(Raster(z.astype(np.float64), viewfinder=vf), routing="d8")
    for edge in (fdir[0, :], fdir[-1, :], fdir[:, 0], fdir[:, -1]):
        edge[...] = 0
    # Explicit unit weights: without them pysheds gives the direction-less (edge) cells none.
    ones = Raster(np.ones(z.shape), viewfinder=vf)
    area = np.asarray(grid.accumulation(fdir, weights=ones, routing="d8"), dtype=np.float64)
    area *= cell_x * cell_y
    h, w = z.shape
    step = {64: (-1, 0), 128: (-1, 1), 1: (0, 1), 2: (1, 1), 4: (1, 0), 8: (1, -1),
            16: (0, -1), 32: (-1, -1)}
    rec = -np.ones(h * w)
    codes = np.asarray(fdir)
    for i in range(h * w):
        d = step.get(int(codes.flat[i]))
        if d is not None:
            rec[i] = (i // w + d[0]) * w + i % w + d[1]
    return rec.reshape(h, w), area


def main():
    dem = np.load(sys.argv[1]).astype(np.float32)
    cell_x, cell_y = float(sys.argv[2]), float(sys.argv[3])
    out = sys.argv[4]
    os.makedirs(out, exist_ok=True)
    saved = os.dup(1)
    os.dup2(2, 1)  # RichDEM prints its progress on stdout
    try:
        import richdem as rd
        r = rd.rdarray(dem.copy(), no_data=-9999.0)
        fill = np.asarray(rd.FillDepressions(r), dtype=np.float32)
        eps = np.asarray(rd.FillDepressions(rd.rdarray(dem.copy(), no_data=-9999.0), epsilon=True),
                         dtype=np.float32)
    finally:
        os.dup2(saved, 1)
    import fastscapelib as fs
    grid = fs.RasterGrid(list(eps.shape), [cell_y, cell_x], fs.NodeStatus.FIXED_VALUE)
    graph = fs.FlowGraph(grid, [fs.SingleFlowRouter()])
    graph.update_routes(eps.astype(np.float64))
    area = np.asarray(graph.accumulate(1.0), dtype=np.float64).reshape(eps.shape)
    np.save(f"{out}/ps_receiver.npy", pysheds_d8(eps, cell_x, cell_y)[0])
    for name, f in (("rd_fill_raised", fill), ("rd_fill_eps_raised", eps)):
        idx = np.flatnonzero(f.ravel() != dem.ravel())
        rows = np.stack([idx.astype(np.float64), f.ravel()[idx].astype(np.float64)], 1)
        np.save(f"{out}/{name}.npy", rows)
    np.save(f"{out}/fs_area.npy", area)
    _, ps_area = pysheds_d8(eps, cell_x, cell_y)
    np.save(f"{out}/ps_area.npy", ps_area)
    print({"changed_by_fill": int((fill != dem).sum()), "eps_vs_plain": int((eps != fill).sum())})


if __name__ == "__main__":
    main()
