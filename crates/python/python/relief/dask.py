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

:func:`flow` is not a set of windows: drainage is global. It is the seven passes of relief's
tiled drainage (Barnes 2016 and 2017, as ``relief tile plan -- flow`` runs them on Slurm) as
tasks of the graph, per-tile passes and single passes in turn, each tile's products handed on as
checked bytes; its arrays and network equal :func:`relief.flow` bit for bit. :func:`masks` adds
the two exact passes of the map's height bands and curvature scale and the masks per tile
(``relief tile plan -- masks``); its arrays equal :func:`relief.masks` bit for bit.
"""

from __future__ import annotations

import uuid
from typing import Any, Optional, Tuple

import numpy as np

import relief
from relief import _relief

__all__ = ["amplify", "refine", "assemble", "flow", "masks"]


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


_FLOW_KEYS = ("depressions", "directions", "channel_area", "breach_depth", "breach_length", "mfd_exponent")


def _halo(block: np.ndarray, pads: Tuple[Tuple[int, int], Tuple[int, int]]) -> bytes:
    """A tile's input: its cells and a one-cell margin, NaN off the map, as little-endian f32
    bytes (a worker may receive an array unaligned; bytes it reads as they are)."""
    return np.pad(np.asarray(block, dtype=np.float32), pads, constant_values=np.nan).astype("<f4").tobytes()


class _Layer:
    """One layer of a high-level graph as a dask collection (what
    ``HighLevelGraph.from_collections`` takes as a dependency)."""

    def __init__(self, name: str, graph: Any) -> None:
        self.name, self.graph = name, graph

    def __dask_graph__(self) -> Any:
        return self.graph

    def __dask_layers__(self) -> tuple:
        return (self.name,)

    def __dask_keys__(self) -> list:
        return list(self.graph.layers[self.name].keys())

    def __dask_postcompute__(self) -> Any:
        return (lambda results: results), ()

    def __dask_postpersist__(self) -> Any:
        raise NotImplementedError("an internal layer of relief.dask.flow is not persisted")

    def __dask_tokenize__(self) -> str:
        return self.name


def _assemble_flow(layout: Any, geo: Any, networks: list) -> Tuple[dict, dict]:
    import json

    channels, figures = _relief.flow_assemble(layout, geo, list(networks))
    return json.loads(channels), json.loads(figures)


def _drainage(dem: Any, tile: int, cell_size: Any, settings: dict, what: str) -> dict:
    """The seven phases of the tiled drainage as graph layers, with what the products need:
    ``made`` (layer name -> collection), ``name`` (a layer's name), ``layout``, ``tiles``,
    ``halos`` and the mosaic's ``rows``, ``cols`` and ``tiles_x``."""
    from operator import getitem

    import dask
    from dask.highlevelgraph import HighLevelGraph

    unknown = sorted(set(settings) - set(_FLOW_KEYS))
    if unknown:
        raise ValueError(f"unknown flow settings: {', '.join(unknown)}")
    for key, only in (("depressions", "fill"), ("directions", "d8")):
        if settings.get(key, only) != only:
            raise ValueError(
                f"{key}={settings[key]!r} has no tiled form equal to the single run: relief.dask.{what} "
                f"computes {key}={only!r} only (run relief.flow for the others)"
            )
    area = settings.get("channel_area", 1e6)
    if not isinstance(area, (int, float)) or not (1e-6 <= float(area) <= 1e13):
        raise ValueError(f"channel_area={area!r} must be a positive area in m^2 (at most 1e13)")
    tile = int(tile)
    if tile < 4 or tile > 32768:
        raise ValueError(f"tile={tile} must be between 4 and 32768 cells")
    data = getattr(dem, "data", None)
    lazy = dem if hasattr(dem, "dask") else data if hasattr(data, "dask") else None
    if lazy is not None:
        cell = relief._cell(cell_size)
        if cell is None:
            raise ValueError("a dask array has no cell size: pass cell_size=(x, y) in metres")
        arr, geo = lazy.astype(np.float32), (None, None, None)
    else:
        g = relief._grid(dem, cell_size)
        cell = relief._need_cell(g, "DEM")
        arr, geo = g.array, g.geo
    if arr.ndim != 2 or 0 in arr.shape:
        raise ValueError(f"the DEM must be a non-empty 2-D array, not of shape {arr.shape}")
    h, w = arr.shape
    layout = (w, h, tile, float(cell[0]), float(cell[1]))
    tiles = _relief.flow_tiles(layout)
    n = len(tiles)
    token = uuid.uuid4().hex

    def name(p: str) -> str:
        return f"relief-{what}-{p}-{token}"

    halos = []
    for t, (x, y, tw, th) in enumerate(tiles):
        x0, y0, x1, y1 = max(x - 1, 0), max(y - 1, 0), min(x + tw + 1, w), min(y + th + 1, h)
        pads = ((y0 - (y - 1), (y + th + 1) - y1), (x0 - (x - 1), (x + tw + 1) - x1))
        halos.append(dask.delayed(_halo, pure=True)(arr[y0:y1, x0:x1], pads, dask_key_name=(name("input"), t)))
    ca = float(area)
    # One graph layer per phase (named relief-flow-phaseP-<token>), holding every task of the
    # phase: per tile (key (name, t)) or one task (key name); an output k of a task of several
    # outputs is taken by (getitem, key, k) inside the task that uses it.
    p1, p2, p3, p4, p5, p6, p7 = (name(f"phase{p}") for p in range(1, 8))
    net = name("network")
    one = range(n)
    phases = [
        (p1, {(p1, t): (_relief.flow_phase1, layout, t, (name("input"), t)) for t in one}, halos),
        (p2, {p2: (_relief.flow_phase2, layout, [(getitem, (p1, t), 1) for t in one])}, [p1]),
        (p3, {(p3, t): (_relief.flow_phase3, layout, t, (getitem, (p1, t), 0), p2) for t in one}, [p1, p2]),
        (p4, {p4: (_relief.flow_phase4, layout, [(getitem, (p3, t), 1) for t in one])}, [p3]),
        (p5, {(p5, t): (_relief.flow_phase5, layout, t, (getitem, (p3, t), 0), (getitem, p4, t), ca)
              for t in one}, [p3, p4]),
        (p6, {p6: (_relief.flow_phase6, layout, [(getitem, (p5, t), 3) for t in one])}, [p5]),
        (p7, {(p7, t): (_relief.flow_phase7, layout, t, (getitem, (p3, t), 0), (getitem, p4, t),
                        (getitem, p6, t), (name("input"), t), ca) for t in one}, [p3, p4, p6, *halos]),
        (net, {net: (_assemble_flow, layout, geo, [(getitem, (p7, t), 3) for t in one])}, [p7]),
    ]
    made: dict = {}
    for layer, tasks, deps in phases:
        colls = [made[d] if isinstance(d, str) else d for d in deps]
        made[layer] = _Layer(layer, HighLevelGraph.from_collections(layer, tasks, dependencies=colls))
    tiles_x = -(-w // tile)
    rows = tuple(tiles[t][3] for t in range(0, n, tiles_x))
    cols = tuple(tiles[t][2] for t in range(tiles_x))
    return dict(made=made, name=name, layout=layout, tiles=tiles, halos=halos, geo=geo, rows=rows,
                cols=cols, tiles_x=tiles_x, ca=ca)


def flow(dem: Any, *, tile: int = 1024, cell_size: Any = None, **settings: Any) -> dict:
    """:func:`relief.flow` as a Dask graph of relief's tiled drainage: per tile of ``tile`` x
    ``tile`` cells a task of phase 1 (local filling), one task of phase 2 (the spill levels of
    all tiles), per tile phase 3 (filled tile, directions, local accumulation), one task of
    phase 4 (the flats and flows crossing tile edges), per tile phase 5 (final filled surface,
    directions, area), one task of phase 6 (watersheds, HAND bases and Strahler orders across
    tile edges), per tile phase 7 (Strahler order, watersheds, HAND). Each task holds about one
    tile; the single tasks hold the tiles' perimeters.

    Returns a dict like :func:`relief.flow`'s: dask arrays ``conditioned``, ``direction``,
    ``area``, ``strahler``, ``watersheds``, ``hand`` (one chunk per tile) and delayed values
    ``channels`` (the GeoJSON network as a dict) and ``figures``; compute them together
    (``dask.compute(result)``) to run the graph once. Equal bit for bit to :func:`relief.flow`
    with the same settings. ``dem``: as for :func:`relief.flow`, or a dask array (kept lazy:
    each tile's task reads its own slice; ``cell_size`` is then required). Only
    ``depressions="fill"`` and ``directions="d8"`` (the defaults) have a tiled form."""
    from operator import getitem

    import dask.array as da
    from dask.delayed import Delayed
    from dask.highlevelgraph import HighLevelGraph

    g = _drainage(dem, tile, cell_size, settings, "flow")
    made, name, tiles_x = g["made"], g["name"], g["tiles_x"]
    one = range(len(g["tiles"]))
    p5, p7, net = name("phase5"), name("phase7"), name("network")

    def mosaic(phase: str, k: int, product: str) -> Any:
        layer = name(product)
        tasks = {(layer, t // tiles_x, t % tiles_x): (getitem, (phase, t), k) for t in one}
        graph = HighLevelGraph.from_collections(layer, tasks, dependencies=[made[phase]])
        return da.Array(graph, layer, (g["rows"], g["cols"]), dtype=np.float32)

    out = {p: mosaic(p5, k, p) for k, p in enumerate(("conditioned", "direction", "area"))}
    out.update({p: mosaic(p7, k, p) for k, p in enumerate(("strahler", "watersheds", "hand"))})
    for k, p in enumerate(("channels", "figures")):
        layer = name(p)
        graph = HighLevelGraph.from_collections(layer, {layer: (getitem, net, k)}, dependencies=[made[net]])
        out[p] = Delayed(layer, graph)
    return out


_MASK_KEYS = ("flow", "height_bands", "rock_slope", "wet_index")


def _pick(d: dict, k: str) -> Any:
    return d[k]


def masks(dem: Any, *, tile: int = 1024, cell_size: Any = None, **settings: Any) -> dict:
    """:func:`relief.masks` as a Dask graph: the seven passes of :func:`flow`, then per tile
    the first count of the map's heights and ``|profile curvature|`` by the high 16 bits of
    their order key, one task locating the bins of the height quartiles (unless
    ``height_bands`` are given) and of the curvature's 95th percentile, per tile the count
    within those bins, one task giving the exact values, and per tile the masks and splat
    weights. Each task holds about one tile (the count tasks 65536 counts per statistic).

    Returns a dict like :func:`relief.masks`'s: dask arrays ``slope``, ``profile_curvature``,
    ``plan_curvature``, ``area``, ``wetness``, ``hand``, ``height_band`` (one chunk per tile)
    and ``splat`` ``(rows, columns, 4)``, and a delayed ``scales`` (the height bands and the
    curvature scale); compute them together to run the graph once. Equal bit for bit to
    :func:`relief.masks` with the same settings (``flow``: ``depressions="fill"`` and
    ``directions="d8"`` only; no erosion rasters)."""
    import json
    from operator import getitem

    import dask.array as da
    from dask.delayed import Delayed
    from dask.highlevelgraph import HighLevelGraph

    unknown = sorted(set(settings) - set(_MASK_KEYS))
    if unknown:
        raise ValueError(f"unknown masks settings: {', '.join(unknown)}")
    flow_settings = dict(settings.get("flow") or {})
    g = _drainage(dem, tile, cell_size, flow_settings, "masks")
    sj = json.dumps(settings)
    _relief.masks_check(sj)
    made, name, layout, tiles_x = g["made"], g["name"], g["layout"], g["tiles_x"]
    one = range(len(g["tiles"]))
    p3, p4, p7 = name("phase3"), name("phase4"), name("phase7")
    cnt, tg, fine, sc, mk = (name(p) for p in ("counts", "targets", "fine", "scales", "masks"))
    inp = lambda t: (name("input"), t)  # noqa: E731
    layers = [
        (cnt, {(cnt, t): (_relief.masks_counts, layout, t, inp(t)) for t in one}, g["halos"]),
        (tg, {tg: (_relief.masks_targets, sj, [(cnt, t) for t in one])}, [cnt]),
        (fine, {(fine, t): (_relief.masks_fine, layout, t, inp(t), tg) for t in one}, [tg, *g["halos"]]),
        (sc, {sc: (_relief.masks_scales, tg, [(fine, t) for t in one])}, [tg, fine]),
        (mk, {(mk, t): (_relief.masks_tile, layout, t, inp(t), (getitem, (p3, t), 0), (getitem, p4, t),
                        (getitem, (p7, t), 2), sj, sc) for t in one}, [p3, p4, p7, sc, *g["halos"]]),
    ]
    for layer, tasks, deps in layers:
        colls = [made[d] if isinstance(d, str) else d for d in deps]
        made[layer] = _Layer(layer, HighLevelGraph.from_collections(layer, tasks, dependencies=colls))
    chunks = (g["rows"], g["cols"])
    out = {}
    for m in ("slope", "profile_curvature", "plan_curvature", "area", "wetness", "hand", "height_band"):
        layer = name(m)
        tasks = {(layer, t // tiles_x, t % tiles_x): (_pick, (getitem, (mk, t), 0), m) for t in one}
        graph = HighLevelGraph.from_collections(layer, tasks, dependencies=[made[mk]])
        out[m] = da.Array(graph, layer, chunks, dtype=np.float32)
    layer = name("splat")
    tasks = {
        (layer, t // tiles_x, t % tiles_x, 0): (np.reshape, (getitem, (mk, t), 1), (th, tw, 4))
        for t, (_, _, tw, th) in zip(one, g["tiles"])
    }
    graph = HighLevelGraph.from_collections(layer, tasks, dependencies=[made[mk]])
    out["splat"] = da.Array(graph, layer, (*chunks, (4,)), dtype=np.float32)
    layer = name("scales-json")
    graph = HighLevelGraph.from_collections(layer, {layer: (json.loads, sc)}, dependencies=[made[sc]])
    out["scales"] = Delayed(layer, graph)
    return out
