"""The xarray accessor: ``da.relief.amplify(exemplar, factor=16, ...)``, ``da.relief.refine(...)``
on a 2-D ``DataArray`` whose last two dimensions are (y, x) with regular coordinates (cell
centres, as rioxarray makes them). The result has the finer grid's coordinates (the same outer
edges), the input's attributes and, when rioxarray is installed and the input has a CRS, the
same ``rio`` CRS. A dask-backed DataArray is computed chunk by chunk as exact windows
(:mod:`relief.dask`); its result is dask-backed too.
"""

from __future__ import annotations

from typing import Any, Tuple

import numpy as np
import xarray as xr

import relief


def _rio_crs(da: xr.DataArray) -> Any:
    try:
        import rioxarray  # noqa: F401
    except ImportError:
        return None
    try:
        return da.rio.crs
    except Exception:  # no spatial dimensions rioxarray recognises
        return None


def _spacing(c: np.ndarray, name: str) -> float:
    if c.size < 2:
        raise ValueError(f"the {name} coordinate needs at least 2 values to give a cell size")
    d = np.diff(c.astype(np.float64))
    if not np.allclose(d, d[0], rtol=1e-6, atol=0):
        raise ValueError(f"the {name} coordinate is not regular")
    return float(d[0])


@xr.register_dataarray_accessor("relief")
class ReliefAccessor:
    """``da.relief``: relief's jobs on a DataArray, keeping coordinates and CRS."""

    def __init__(self, da: xr.DataArray) -> None:
        if da.ndim != 2:
            raise ValueError(f"relief works on 2-D DataArrays (y, x), this one has {da.ndim} dimensions")
        self._da = da

    @property
    def transform(self) -> Tuple[float, float, float, float, float, float]:
        """The rasterio-style affine 6-tuple of the grid (from its cell-centre coordinates)."""
        ydim, xdim = self._da.dims
        x = np.asarray(self._da[xdim].values)
        y = np.asarray(self._da[ydim].values)
        dx, dy = _spacing(x, xdim), _spacing(y, ydim)
        return (dx, 0.0, float(x[0]) - dx / 2, 0.0, dy, float(y[0]) - dy / 2)

    def cell_size(self) -> Tuple[float, float]:
        """Ground cell size in metres (relief's rule for the CRS; coordinates as metres when
        there is none)."""
        crs = _rio_crs(self._da)
        t = self.transform
        if crs is not None:
            c = relief.ground_cell_size(t, crs, self._da.shape[0])
            if c is not None:
                return c
        return (abs(t[0]), abs(t[4]))

    def _wrap(self, out: Any, scale: int) -> xr.DataArray:
        da = self._da
        ydim, xdim = da.dims
        if scale == 1:
            xs, ys = da[xdim].values, da[ydim].values
        else:
            a, _, c, _, e, f = self.transform
            ny, nx = out.shape
            xs = c + (np.arange(nx) + 0.5) * a / scale
            ys = f + (np.arange(ny) + 0.5) * e / scale
        res = xr.DataArray(out, dims=(ydim, xdim), coords={xdim: xs, ydim: ys}, attrs=dict(da.attrs), name=da.name)
        crs = _rio_crs(da)
        if crs is not None:
            res = res.rio.write_crs(crs)
        return res

    def _dask(self) -> bool:
        return self._da.chunks is not None

    def amplify(self, exemplar: Any, factor: int = 16, *, cell_size: Any = None, **kw: Any) -> xr.DataArray:
        """:func:`relief.amplify` of the DataArray (:func:`relief.dask.amplify` when it is
        dask-backed); coordinates and CRS of the amplified grid."""
        cell = cell_size if cell_size is not None else self.cell_size()
        if self._dask():
            from relief import dask as rdask

            out = rdask.amplify(self._da.data, exemplar, factor, cell_size=cell, **kw)
        else:
            out = relief.amplify(np.asarray(self._da.values), exemplar, factor, cell_size=cell, **kw)
        return self._wrap(out, factor)

    def refine(self, *, cell_size: Any = None, **kw: Any) -> xr.DataArray:
        """:func:`relief.refine` of the DataArray (:func:`relief.dask.refine` when it is
        dask-backed); coordinates and CRS of the refined grid."""
        cell = cell_size if cell_size is not None else self.cell_size()
        levels = int(kw.get("extra_levels", relief.defaults("refine")["extra_levels"]))
        if self._dask():
            from relief import dask as rdask

            out = rdask.refine(self._da.data, cell_size=cell, **kw)
        else:
            out = relief.refine(np.asarray(self._da.values), cell_size=cell, **kw)
        return self._wrap(out, 2**levels)

    def flow(self, *, cell_size: Any = None, **kw: Any) -> xr.Dataset:
        """:func:`relief.flow` of the DataArray as a Dataset of its rasters on the same grid
        (the channel network in ``attrs["channels"]``)."""
        cell = cell_size if cell_size is not None else self.cell_size()
        r = relief.flow(np.asarray(self._da.values), cell_size=cell, **kw)
        channels = r.pop("channels")
        ds = xr.Dataset({k: self._wrap(v, 1) for k, v in r.items()})
        ds.attrs["channels"] = channels
        return ds

    def erode(self, *, cell_size: Any = None, **kw: Any) -> xr.Dataset:
        """:func:`relief.erode` of the DataArray as a Dataset (terrain, erosion, deposition)."""
        cell = cell_size if cell_size is not None else self.cell_size()
        r = relief.erode(np.asarray(self._da.values), cell_size=cell, **kw)
        return xr.Dataset({k: self._wrap(v, 1) for k, v in r.items()})

