"""relief on Dask: amplify and refine a terrain as a ``dask.array`` whose every chunk is computed
alone, as its own window of the output, on any Dask scheduler (threads, a
``distributed.LocalCluster``, dask-jobqueue on Slurm, dask-kubernetes).

relief's windows are exact: a window of an amplified or refined terrain equals the same window
of the whole run bit for bit (the library computes it on a crop of its input with a halo wide
enough for every dependency, and seeds each primitive by its position in the whole grid). So
the assembled array equals :func:`relief.amplify` / :func:`relief.refine` with
``landform=False`` exactly, whatever the chunking and the number of workers. (The landform pass
routes water over the whole raster and has no windows: run :func:`relief.flow` or
:func:`relief.erode` on the result instead.)

The work that is not per window runs once, here, when the array is built: for ``amplify``
every x4 step but the last (a sixteenth of the last one's cells) and the last step's
dictionary; for ``refine`` the wavelet analysis of the input. This plan is one task of the
graph, pickled once to each worker that needs it.
"""

from __future__ import annotations

import uuid
from typing import Any, Optional, Tuple

import numpy as np

import relief
from relief import _relief

__all__ = ["amplify", "refine", "assemble"]


def _no_landform(settings: dict) -> None:
    if settings.pop("landform", False):
        raise ValueError(
            "relief.dask computes windows, and the landform pass routes water over the whole "
            "raster: run relief.flow or relief.erode on the result instead (or omit landform)"
        )


def _window(plan: Any, x: int, y: int, w: int, h: int) -> np.ndarray:
    return plan.window(x, y, w, h)


def _input(x: Any) -> Any:
    """A dask array (or dask-backed DataArray) computed in memory; anything else as it is."""
    data = getattr(x, "data", None)
    if data is not None and hasattr(data, "dask"):
        x = data
    if hasattr(x, "dask") and hasattr(x, "compute"):
        return np.asarray(x.compute())
    return x


def assemble(plan: Any, chunks: Any = 1024) -> Any:
    """The output of a plan (``relief._relief.AmplifyPlan`` / ``RefinePlan``) as a dask array of
    float32 whose chunk ``(i, j)`` is ``plan.window`` of its cells. ``chunks``: an int, a
    ``(rows, columns)`` pair or dask's explicit chunk tuples."""
    import dask
    import dask.array as da
    from dask.array.core import normalize_chunks

    w, h = plan.output_size()
    rows, cols = normalize_chunks(chunks, shape=(h, w), dtype=np.float32)
    token = uuid.uuid4().hex
    p = dask.delayed(plan, name=f"relief-plan-{token}", pure=False, traverse=False)
    window = dask.delayed(_window, pure=True)
    blocks = []
    y = 0
    for ch in rows:
        row = []
        x = 0
        for cw in cols:
            row.append(da.from_delayed(window(p, x, y, cw, ch), shape=(ch, cw), dtype=np.float32))
            x += cw
        blocks.append(row)
        y += ch
    return da.block(blocks)


def amplify(
    coarse: Any,
    exemplar: Any,
    factor: int = 16,
    *,
    chunks: Any = 1024,
    cell_size: Any = None,
    paper: bool = False,
    progress: Any = None,
    **settings: Any,
) -> Any:
    """:func:`relief.amplify` as a dask array of exact windows (``chunks`` cells each; the
    landform pass does not apply). ``coarse`` may be a numpy or dask array, a dask-backed
    DataArray (its values are computed: the coarse input is 1/factor^2 of the output), a
    :class:`relief.Raster` or a path. Settings as for :func:`relief.amplify`."""
    _no_landform(settings)
    steps = relief.factor_steps(factor)
    settings = dict(settings, steps=settings.get("steps", steps))
    g = relief._grid(_input(coarse), cell_size)
    cell = relief._need_cell(g, "coarse input")
    f = 4 ** settings["steps"]
    ex, ex_cell = relief._exemplar(_input(exemplar), (cell[0] / f, cell[1] / f))
    plan = _relief.amplify_plan(
        g.array, cell, g.geo, ex, ex_cell, relief._json(settings), bool(paper), relief._progress(progress)
    )
    return assemble(plan, chunks)


def refine(terrain: Any, *, chunks: Any = 1024, cell_size: Any = None, **settings: Any) -> Any:
    """:func:`relief.refine` as a dask array of exact windows (``chunks`` cells each; the landform
    pass does not apply). Settings as for :func:`relief.refine`."""
    _no_landform(settings)
    paper = settings.get("model") == "paper"
    g = relief._grid(_input(terrain), cell_size)
    cell = relief._need_cell(g, "terrain")
    plan = _relief.refine_plan(g.array, cell, g.geo, relief._json(settings), paper)
    return assemble(plan, chunks)


def plan_transform(plan: Any) -> Optional[Tuple[float, ...]]:
    """The rasterio-style affine 6-tuple of a plan's whole output, if its input had one."""
    return relief._affine(plan.transform)
