"""relief: terrain amplification, synthesis, refinement, drainage and erosion on numpy arrays.

The jobs are the Rust library's (the same code the ``relief`` command runs): each settings
keyword argument is a field of the library's settings type, with its name, its default (from
the Rust ``Default``, see :func:`defaults`), its checks and its error messages. Bad parameters
raise ``ValueError`` with the library's message, unreadable or unwritable files ``OSError``.

Arrays go in as 2-D float32 (other dtypes are converted; the library copies the input once into
its own grid) and come out as float32 arrays handed over without a copy. A georeference travels
as a rasterio-style ``Affine`` (``affine.Affine`` when installed, else the 6-tuple
``(a, b, c, d, e, f)``) plus the CRS (WKT, ``EPSG:<code>`` or a rasterio ``CRS``), on a
:class:`Raster` or on an xarray ``DataArray`` (``da.relief.amplify(...)``, see
:mod:`relief.xarray`). A :class:`Raster` in gives a :class:`Raster` out; an array gives an array.

Work runs with the GIL released, on a thread of its own; ``progress`` takes a callable
``progress(phase, done, total)`` (or ``True`` for a tqdm bar when tqdm is installed), and
Ctrl-C returns from any call within a tenth of a second (``KeyboardInterrupt``). The library's
notes (what each amplification step did, the landform pass) go to the ``relief`` logger.
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass, field
from typing import Any, Callable, Optional, Sequence, Tuple, Union

import numpy as np

from . import _relief

__all__ = [
    "Raster",
    "read",
    "write",
    "defaults",
    "amplify",
    "refine",
    "synthesize",
    "quilt",
    "volume",
    "flow",
    "erode",
    "masks",
    "ground_cell_size",
    "factor_steps",
]

__version__ = _relief.__version__

log = logging.getLogger("relief")

ArrayLike = Any
PathLike = Union[str, "os.PathLike[str]"]


@dataclass
class Raster:
    """A raster with its georeference: what :func:`read` returns and what jobs accept.

    ``array`` is float32, row 0 north, voids NaN; ``transform`` a rasterio-style ``Affine`` (or
    its 6-tuple ``(a, b, c, d, e, f)``), ``crs`` the CRS as WKT (or anything :func:`write`
    accepts), ``cell_size`` the ground cell size ``(x, y)`` in metres. ``georef`` is the
    library's own georeference (JSON) of a raster relief read or computed: its GeoTIFF tags are
    written back verbatim (any CRS, as the ``relief`` command does) while ``transform`` is
    unchanged.
    """

    array: np.ndarray
    transform: Any = None
    crs: Any = None
    cell_size: Optional[Tuple[float, float]] = None
    nodata: Optional[float] = None
    georef: Optional[str] = field(default=None, repr=False, compare=False)


def _affine(gdal: Optional[Sequence[float]]) -> Any:
    """The rasterio ``Affine`` of a GDAL geotransform ``(x0, dx, rx, y0, ry, dy)``."""
    if gdal is None:
        return None
    x0, dx, rx, y0, ry, dy = gdal
    t = (dx, rx, x0, ry, dy, y0)
    try:
        from affine import Affine

        return Affine(*t)
    except ImportError:
        return t


def _gdal(transform: Any) -> Optional[Tuple[float, ...]]:
    """The GDAL geotransform of a rasterio ``Affine`` or its 6- (or 9-) tuple."""
    if transform is None:
        return None
    t = tuple(float(v) for v in tuple(transform)[:6])
    if len(t) != 6:
        raise ValueError(f"transform must be an Affine or a 6-tuple (a, b, c, d, e, f), not {transform!r}")
    a, b, c, d, e, f = t
    return (c, a, b, f, d, e)


def _crs_text(crs: Any) -> Optional[str]:
    """CRS text the library reads: ``EPSG:<code>`` when the CRS has one, else its WKT."""
    if crs is None:
        return None
    if isinstance(crs, str):
        return crs
    to_epsg = getattr(crs, "to_epsg", None)
    if to_epsg is not None:
        code = to_epsg()
        if code:
            return f"EPSG:{code}"
    to_wkt = getattr(crs, "to_wkt", None)
    if to_wkt is not None:
        # WKT 1, which the library reads (rasterio's and pyproj's CRS both take `version`).
        try:
            return to_wkt(version="WKT1_GDAL")
        except TypeError:
            return to_wkt()
    return str(crs)


def _f32(array: Any) -> np.ndarray:
    # Aligned float32 (a copy only when the dtype or the alignment differs: numpy can hold
    # unaligned buffers, e.g. unpickled ones, which the native side cannot view).
    a = np.require(array, dtype=np.float32, requirements=["A"])
    if a.ndim != 2:
        raise ValueError(f"expected a 2-D array (rows, columns), got {a.ndim} dimensions")
    return a


def _cell(cell_size: Any) -> Optional[Tuple[float, float]]:
    if cell_size is None:
        return None
    if np.isscalar(cell_size):
        return (float(cell_size), float(cell_size))
    x, y = cell_size
    return (float(x), float(y))


def ground_cell_size(transform: Any, crs: Any, height: int) -> Optional[Tuple[float, float]]:
    """Ground cell size in metres of a grid ``height`` rows high, as relief reads a GeoTIFF:
    geographic grids at the centre latitude, Web Mercator scaled by cos(latitude), other
    projections as metres. ``None`` without a usable transform."""
    t = _gdal(transform)
    if t is None:
        return None
    return _relief.ground_cell_size(t, _crs_text(crs), int(height))


@dataclass
class _Grid:
    array: np.ndarray
    cell: Optional[Tuple[float, float]]
    transform: Optional[Tuple[float, ...]]
    crs: Any
    raster: bool
    georef: Optional[str] = None

    @property
    def geo(self) -> Tuple[Any, Optional[str], Optional[str]]:
        """The georeference as the native functions take it."""
        return (self.transform, _crs_text(self.crs), self.georef)


def _grid(x: Any, cell_size: Any = None, transform: Any = None, crs: Any = None) -> _Grid:
    """An input as an array with what is known of its cell size and georeference."""
    if isinstance(x, (str, os.PathLike)):
        x = read(x)
    georef = None
    if isinstance(x, Raster):
        a = _f32(x.array)
        if transform is None and crs is None:
            georef = x.georef
        transform = x.transform if transform is None else transform
        crs = x.crs if crs is None else crs
        cell = _cell(cell_size) or _cell(x.cell_size)
        raster = True
    else:
        a = _f32(x)
        cell = _cell(cell_size)
        raster = False
    if cell is None and transform is not None:
        cell = ground_cell_size(transform, crs, a.shape[0])
    return _Grid(a, cell, _gdal(transform), crs, raster, georef)


def _need_cell(g: _Grid, what: str) -> Tuple[float, float]:
    if g.cell is None:
        raise ValueError(
            f"the {what} has no cell size: pass cell_size=(x, y) in metres (or a Raster or "
            f"transform that gives one)"
        )
    return g.cell


def _progress(progress: Any) -> Optional[Callable[[str, int, int], None]]:
    """The callback of ``progress``: a callable, ``True`` (tqdm when installed), or None."""
    if progress is None or progress is False:
        return None
    if callable(progress):
        return progress
    try:
        from tqdm.auto import tqdm
    except ImportError:
        def logged(phase: str, done: int, total: int) -> None:
            log.info("%s: %d/%d", phase, done, total)

        return logged
    state: dict = {}

    def bar(phase: str, done: int, total: int) -> None:
        b = state.get("bar")
        if b is None or state.get("phase") != phase:
            if b is not None:
                b.close()
            b = state["bar"] = tqdm(total=total or None, desc=phase)
            state["phase"] = phase
        b.n = done
        b.refresh()

    return bar


def _json(settings: dict) -> str:
    try:
        return json.dumps(settings, allow_nan=False)
    except (TypeError, ValueError) as e:
        raise ValueError(f"settings must be JSON values (numbers, strings, lists, dicts): {e}") from None


def _notes(notes: Sequence[str]) -> None:
    for n in notes:
        log.info("%s", n)


def defaults(job: str) -> dict:
    """The library's default settings of a job (``amplify``, ``amplify_paper``, ``refine``,
    ``refine_paper``, ``synthesize``, ``quilt``, ``volume``, ``flow``, ``erode``, ``masks``):
    the keyword arguments the job takes and their defaults."""
    return json.loads(_relief.defaults(job))


def factor_steps(factor: int) -> int:
    """Number of x4 steps of an amplification factor per axis (4, 16, 64, ... 4096)."""
    f, steps = int(factor), 0
    if f != factor:
        raise ValueError(f"invalid factor {factor}: must be a power of 4 between 4 and 4096")
    while f > 1 and f % 4 == 0:
        f //= 4
        steps += 1
    if f != 1 or steps == 0 or steps > 6:
        raise ValueError(f"invalid factor {factor}: must be a power of 4 between 4 and 4096")
    return steps


def read(path: PathLike, *, max_cells: Optional[int] = None) -> Raster:
    """Reads any raster relief reads (GeoTIFF, SRTM .hgt, ESRI ASCII, PNG, EXR, NPY/NPZ, raw
    .r16/.r32, .f32 with its sidecar) with its georeference. Raises ``OSError`` for a file that
    cannot be opened and ``ValueError`` for one that cannot be decoded."""
    d = _relief.read(os.fspath(path), max_cells)
    return Raster(
        array=d["array"],
        transform=_affine(d["transform"]),
        crs=d["crs"],
        cell_size=tuple(d["cell_size"]),
        nodata=d["nodata"],
        georef=d["georef"],
    )


def write(path: PathLike, array: Any, transform: Any = None, crs: Any = None, *, cell_size: Any = None) -> None:
    """Writes a raster atomically, the format from the extension (``.tif``, ``.png`` (16-bit),
    ``.exr``, ``.npy``, ``.r16``, ``.r32``, ``.asc``, ``.hgt``, ``.f32``). ``array`` may be a
    :class:`Raster` (its georeference is written unless given here). A GeoTIFF gets the
    transform and, for an EPSG CRS, its GeoTIFF keys, so rasterio reads both back."""
    g = _grid(array, cell_size, transform, crs)
    cell = g.cell or (1.0, 1.0)
    _relief.write(os.fspath(path), g.array, cell, g.geo)


def _result(g: _Grid, array: np.ndarray, georef: Optional[str], cell: Optional[Tuple[float, float]]) -> Any:
    if not g.raster:
        return array
    t = None if georef is None else json.loads(georef).get("geotransform")
    return Raster(array=array, transform=_affine(t), crs=g.crs, cell_size=cell, georef=georef)


def _exemplar(exemplar: Any, fallback: Tuple[float, float]) -> Tuple[np.ndarray, Tuple[float, float]]:
    e = _grid(exemplar)
    return e.array, e.cell or fallback


def amplify(
    coarse: Any,
    exemplar: Any,
    factor: int = 16,
    *,
    cell_size: Any = None,
    paper: bool = False,
    landform: Optional[bool] = None,
    window: Optional[Tuple[int, int, int, int]] = None,
    progress: Any = None,
    **settings: Any,
) -> Any:
    """Adds detail to a coarse terrain with the details of an exemplar (Guerin et al. 2016,
    sparse dictionaries, x4 per step): ``relief amplify``.

    ``coarse``: array, :class:`Raster` or path, no voids; ``cell_size`` its cell size in metres
    (default: the Raster's or the transform's). ``exemplar``: array, Raster or path; an array
    without a cell size is taken at the output's cell size (``exemplar_cell_size=`` overrides).
    ``factor``: a power of 4. ``paper``: start from the paper's settings
    (``AmplifySettings::paper``). ``landform``: the drainage-aware landform pass (default on,
    off with ``paper``; skipped for a ``window``). ``window``: ``(x, y, width, height)`` of the
    output only (equal to the same window of the whole run). ``settings``: fields of
    ``AmplifySettings`` (``radius``, ``step``, ``sparsity``, ``dictionary``, ``seed``,
    ``residual_kernel``, ``index_probes``, ...; see ``defaults("amplify")``).
    """
    steps = factor_steps(factor)
    settings = dict(settings, steps=settings.get("steps", steps))
    g = _grid(coarse, cell_size)
    cell = _need_cell(g, "coarse input")
    f = 4 ** settings["steps"]
    ex, ex_cell = _exemplar(exemplar, (cell[0] / f, cell[1] / f))
    out, t, notes = _relief.amplify(
        g.array, cell, g.geo, ex, ex_cell, _json(settings), bool(paper), landform,
        None if window is None else tuple(int(v) for v in window), _progress(progress),
    )
    _notes(notes)
    return _result(g, out, t, (cell[0] / f, cell[1] / f))


def synthesize(
    sketch: Any,
    exemplar: Any,
    *,
    cell_size: Any = None,
    paper: bool = False,
    window: Optional[Tuple[int, int, int, int]] = None,
    progress: Any = None,
    ridges: Any = None,
    rivers: Any = None,
    **settings: Any,
) -> Any:
    """A terrain from a painted sketch (bright = high) and an exemplar DEM, by x4
    amplification steps after a structure step and, by default, landscape evolution with the
    sketch as uplift: ``relief synthesize``. ``settings``: fields of ``SynthesisSettings``
    (``amplify`` (a dict of ``AmplifySettings`` fields, e.g. ``{"steps": 3, "seed": 1}``),
    ``structure``, ``grow`` (None turns it off), ``sketch_cell_size``, ``height_range``);
    ``steps`` and ``seed`` are accepted at the top level as ``amplify``'s. ``paper``: the
    paper's plain method. The sketch's cell size is only used when given (else the
    library's ``sketch_cell_size`` rule applies). ``ridges`` / ``rivers``: stroke layers
    painted beside the sketch (2-D arrays of its shape or an integer fraction of it, bright =
    stroke), as ``--ridges`` / ``--rivers``: ridge lines raise the grown relief, rivers stay
    valley floors (they need the landscape evolution: not with ``paper``)."""
    amp = dict(settings.pop("amplify", {}) or {})
    for k in ("steps", "seed"):
        if k in settings:
            amp[k] = settings.pop(k)
    if amp:
        settings["amplify"] = amp
    g = _grid(sketch, cell_size)
    ex, ex_cell = _exemplar(exemplar, (1.0, 1.0))
    layer = lambda a: None if a is None else _f32(a)
    out, t, notes = _relief.synthesize(
        g.array, g.cell or (1.0, 1.0), ex, ex_cell, _json(settings), bool(paper),
        None if window is None else tuple(int(v) for v in window), _progress(progress),
        layer(ridges), layer(rivers),
    )
    _notes(notes)
    return _result(g, out, t, None)


def refine(
    terrain: Any,
    *,
    cell_size: Any = None,
    landform: Optional[bool] = None,
    window: Optional[Tuple[int, int, int, int]] = None,
    progress: Any = None,
    **settings: Any,
) -> Any:
    """Adds levels of detail by wavelet synthesis (Perez et al.): ``relief refine``.
    ``settings``: fields of ``RefineSettings`` (``extra_levels`` (default 2: x4 per side),
    ``model`` (``"spectral"`` or ``"paper"``, whose defaults then apply), ``method``
    (``"gsa"``/``"lsa"``), ``stats_window``, ``wavelet``, ``seed``, ``fit``, ...; see
    ``defaults("refine")``). ``landform`` and ``window`` as for :func:`amplify`."""
    paper = settings.get("model") == "paper"
    g = _grid(terrain, cell_size)
    cell = _need_cell(g, "terrain")
    out, t, notes = _relief.refine(
        g.array, cell, g.geo, _json(settings), paper, landform,
        None if window is None else tuple(int(v) for v in window), _progress(progress),
    )
    _notes(notes)
    n = 2 ** int(settings.get("extra_levels", defaults("refine")["extra_levels"]))
    return _result(g, out, t, (cell[0] / n, cell[1] / n))


def _split(settings: dict, inner: str, job: str) -> dict:
    """Keyword arguments of a job type with a nested settings type: the nested type's fields
    (``quilt``'s ``settings``, ``volume``'s ``recipe``) may be given at the top level."""
    fields = defaults(job)[inner]
    nested = dict(settings.pop(inner, {}) or {})
    for k in list(settings):
        if k in fields:
            nested[k] = settings.pop(k)
    if nested:
        settings[inner] = nested
    return settings


def _arg(x: Any, cell_size: Any = None) -> Tuple[np.ndarray, Tuple[float, float]]:
    g = _grid(x, cell_size)
    return g.array, g.cell or (1.0, 1.0)


def quilt(
    exemplars: Sequence[Any],
    *,
    guide: Any = None,
    guide_setup: Optional[dict] = None,
    categories: Any = None,
    exemplar_regions: Sequence[Any] = (),
    exemplar_cell_size: Any = None,
    landform: bool = True,
    progress: Any = None,
    **settings: Any,
) -> np.ndarray:
    """Guided patch-based synthesis (Cruz et al. 2015): ``relief quilt``. ``exemplars``: arrays,
    Rasters or paths; ``guide``: the guide DEM (array, Raster or path) and ``guide_setup`` how it
    becomes the guide (``QuiltJob``'s ``guide``, a ``GuideSetup``: ``cell_size``, ``blur``,
    ``range``); ``settings``: fields of ``QuiltJob`` (``size``,
    ``exemplar_categories``, ``auto_categories``, ...) and of its ``Settings`` given at the
    top level or as ``settings={...}`` (``patch_size``, ``overlap``, ``seed``, ``blend``, ...;
    see ``defaults("quilt")``). ``landform``: the CLI's pass over the quilt (default on)."""
    settings = _split(dict(settings), "settings", "quilt")
    if guide_setup is not None:
        settings["guide"] = dict(guide_setup)
    ex = [_arg(e, exemplar_cell_size) for e in exemplars]
    out = _relief.quilt(
        ex,
        None if guide is None else _arg(guide),
        None if categories is None else _arg(categories),
        [_arg(r) for r in exemplar_regions],
        _json(settings),
        bool(landform),
        _progress(progress),
    )
    return out


def volume(
    dem: Any, *, cell_size: Any = None, colours: bool = False, progress: Any = None, **settings: Any
) -> Tuple[np.ndarray, ...]:
    """3-D landforms on an implicit construction tree (Paris et al. 2018): ``relief volume
    --mesh``. Returns ``(vertices, faces)``: ``(n, 3)`` float32 positions in metres (x east,
    y north, z up) and ``(m, 3)`` uint32 counter-clockwise triangles; with ``colours=True``
    also ``(n, 4)`` uint8 sRGB vertex colours (rock by stratum, soil on gentle slopes: what
    ``relief volume --render`` draws and ``--mesh`` writes). ``settings``: fields of
    ``VolumeJob`` (``max_triangles``, ``max_mesh_cells``) and of its ``Recipe`` at the top
    level or as ``recipe={...}`` (``features``, ``sea_level``, ``seed``, ``voxel``, ``scale``,
    ...; see ``defaults("volume")``)."""
    settings = _split(dict(settings), "recipe", "volume")
    g = _grid(dem, cell_size)
    v, f, c = _relief.volume((g.array, _need_cell(g, "DEM")), _json(settings), _progress(progress))
    return (v, f, c) if colours else (v, f)


def flow(dem: Any, *, cell_size: Any = None, progress: Any = None, **settings: Any) -> dict:
    """Drainage: ``relief flow``. Returns a dict of rasters (``conditioned``, ``direction``
    (ESRI codes), ``area`` (m^2), ``strahler``, ``watersheds``, ``hand``) and ``channels`` (the
    GeoJSON network as a dict). ``settings``: fields of ``FlowSettings`` (``depressions``,
    ``directions``, ``channel_area``, ...)."""
    g = _grid(dem, cell_size)
    rasters, channels = _relief.flow(
        (g.array, _need_cell(g, "DEM")), g.geo, _json(settings), _progress(progress)
    )
    rasters["channels"] = json.loads(channels)
    return rasters


def erode(dem: Any, *, cell_size: Any = None, uplift: Any = None, progress: Any = None, **settings: Any) -> dict:
    """Erosion: ``relief erode``. Returns a dict of rasters ``terrain``, ``erosion``,
    ``deposition`` (metres). ``settings``: fields of ``ErodeSettings`` (``preset``, ``years``,
    ``k``, ``m``, ``n``, ``hydraulic_iterations``, ``fan_gradient``, ``seed``, ...); ``uplift``: a raster of
    rates (m/yr) on the DEM's grid."""
    g = _grid(dem, cell_size)
    cell = _need_cell(g, "DEM")
    up = None if uplift is None else (_f32(uplift.array if isinstance(uplift, Raster) else uplift), cell)
    return _relief.erode((g.array, cell), up, _json(settings), _progress(progress))


def masks(
    dem: Any, *, cell_size: Any = None, erosion: Any = None, deposition: Any = None, progress: Any = None, **settings: Any
) -> dict:
    """Terrain masks and the splat map: ``relief masks``. Returns a dict of mask rasters by
    name and ``splat``, the ``(rows, columns, 4)`` layer weights. ``settings``: fields of
    ``MasksSettings`` (``flow``, ``height_bands``, ``rock_slope``, ``wet_index``)."""
    g = _grid(dem, cell_size)
    cell = _need_cell(g, "DEM")
    e = None if erosion is None else (_f32(erosion), cell)
    d = None if deposition is None else (_f32(deposition), cell)
    rasters, splat = _relief.masks((g.array, cell), e, d, _json(settings), _progress(progress))
    rasters["splat"] = splat.reshape(g.array.shape[0], g.array.shape[1], 4)
    return rasters


def _register_xarray() -> None:
    try:
        from . import xarray as _xr  # noqa: F401
    except ImportError:
        pass


_register_xarray()
