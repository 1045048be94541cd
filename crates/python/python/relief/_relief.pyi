"""Type stubs of the native module ``relief._relief`` (PyO3). Use the wrappers in ``relief``:
they take keyword arguments, Rasters, paths and rasterio ``Affine``s and build the arguments
below (settings as the JSON of the keyword arguments, georeferences as ``Geo``)."""

from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

F32 = npt.NDArray[np.float32]
U32 = npt.NDArray[np.uint32]
U8 = npt.NDArray[np.uint8]
Cell = Tuple[float, float]
# GDAL geotransform (x0, dx, rx, y0, ry, dy).
Transform = Tuple[float, float, float, float, float, float]
# (transform, CRS text, the library's GeoRef as JSON of a raster relief read or computed).
Geo = Tuple[Optional[Transform], Optional[str], Optional[str]]
Window = Tuple[int, int, int, int]
Progress = Optional[Callable[[str, int, int], None]]
Grid = Tuple[F32, Cell]

__version__: str

def read(path: str, max_cells: Optional[int] = None) -> Dict[str, object]:
    """Reads any raster relief-io knows: ``array``, ``cell_size``, ``transform``, ``crs``,
    ``georef``, ``nodata``, ``format``, ``dtype``."""

def write(path: str, array: F32, cell_size: Cell, geo: Geo) -> None:
    """Writes a float32 array (format from the extension) with its georeference."""

def ground_cell_size(transform: Transform, crs: Optional[str], height: int) -> Optional[Cell]:
    """Ground cell size in metres, as relief-io derives it for a GeoTIFF."""

def last_run_seconds() -> float:
    """Wall time of the last job run from this thread, on the job's own thread."""

def defaults(job: str) -> str:
    """The library's default settings of a job, as JSON."""

def amplify(
    coarse: F32, cell_size: Cell, geo: Geo, exemplar: F32, exemplar_cell_size: Cell, settings: str,
    paper: bool, landform: Optional[bool], window: Optional[Window], progress: Progress,
) -> Tuple[F32, Optional[str], List[str]]:
    """``relief amplify``: (raster, georeference JSON, notes)."""

def synthesize(
    sketch: F32, cell_size: Cell, exemplar: F32, exemplar_cell_size: Cell, settings: str, paper: bool,
    window: Optional[Window], progress: Progress, ridges: Optional[F32] = None,
    rivers: Optional[F32] = None,
) -> Tuple[F32, Optional[str], List[str]]:
    """``relief synthesize``: (raster, georeference JSON, notes)."""

def refine(
    input: F32, cell_size: Cell, geo: Geo, settings: str, paper: bool, landform: Optional[bool],
    window: Optional[Window], progress: Progress,
) -> Tuple[F32, Optional[str], List[str]]:
    """``relief refine``: (raster, georeference JSON, notes)."""

def quilt(
    exemplars: Sequence[Grid], guide: Optional[Grid], categories: Optional[Grid],
    exemplar_regions: Sequence[Grid], settings: str, landform: bool, progress: Progress,
) -> F32:
    """``relief quilt``."""

def volume(dem: Grid, settings: str, progress: Progress) -> Tuple[F32, U32, U8]:
    """``relief volume --mesh``: (vertices (n, 3) in metres, faces (m, 3), sRGB vertex colours
    (n, 4))."""

def flow(dem: Grid, geo: Geo, settings: str, progress: Progress) -> Tuple[Dict[str, F32], str]:
    """``relief flow``: (rasters by name, channels GeoJSON)."""

def erode(dem: Grid, uplift: Optional[Grid], settings: str, progress: Progress) -> Dict[str, F32]:
    """``relief erode``: terrain, erosion, deposition."""

def masks(
    dem: Grid, erosion: Optional[Grid], deposition: Optional[Grid], settings: str, progress: Progress
) -> Tuple[Dict[str, F32], F32]:
    """``relief masks``: (masks by name, splat weights (rows, columns * 4))."""

class AmplifyPlan:
    """The last x4 step of an amplification: any window of its output (picklable)."""

    @property
    def transform(self) -> Optional[Transform]: ...
    def output_size(self) -> Tuple[int, int]: ...
    def window(self, x: int, y: int, width: int, height: int) -> F32: ...

class RefinePlan:
    """The analysis of a refinement: any window of the refined terrain (picklable)."""

    @property
    def transform(self) -> Optional[Transform]: ...
    def output_size(self) -> Tuple[int, int]: ...
    def window(self, x: int, y: int, width: int, height: int) -> F32: ...

def amplify_plan(
    coarse: F32, cell_size: Cell, geo: Geo, exemplar: F32, exemplar_cell_size: Cell, settings: str,
    paper: bool, progress: Progress,
) -> AmplifyPlan:
    """Every amplification step but the last (``relief.dask.amplify``)."""

def refine_plan(input: F32, cell_size: Cell, geo: Geo, settings: str, paper: bool) -> RefinePlan:
    """The wavelet analysis of a terrain (``relief.dask.refine``)."""

def _amplify_plan(bytes: bytes, settings_json: str, paper: bool, transform: Optional[Transform]) -> AmplifyPlan:
    """Unpickles an AmplifyPlan."""

def _refine_plan(
    bytes: bytes, size: Tuple[int, int], cell_size: Cell, geo: Geo, settings_json: str, paper: bool
) -> RefinePlan:
    """Unpickles a RefinePlan."""

# The passes of the tiled drainage (relief.dask.flow); Layout: (width, height, tile, cell_x,
# cell_y); every product is the checked byte form of relief-landscape's flow::tiled.
Layout = Tuple[int, int, int, float, float]

def flow_tiles(layout: Layout) -> List[Tuple[int, int, int, int]]:
    """Each tile's (x, y, width, height)."""

def flow_phase1(layout: Layout, t: int, input: bytes) -> Tuple[bytes, bytes]:
    """Phase 1 of tile t from the tile and its one-cell margin (little-endian f32 bytes):
    (local fill, fill graph)."""

def flow_phase2(layout: Layout, graphs: List[bytes]) -> List[bytes]:
    """Phase 2: every tile's levels."""

def flow_phase3(layout: Layout, t: int, fill: bytes, levels: List[bytes]) -> Tuple[bytes, bytes]:
    """Phase 3 of tile t: (routed, port graph)."""

def flow_phase4(layout: Layout, ports: List[bytes]) -> List[bytes]:
    """Phase 4: every tile's inflows."""

def flow_phase5(
    layout: Layout, t: int, routed: bytes, inflow: bytes, channel_area: float
) -> Tuple[F32, F32, F32, bytes]:
    """Phase 5 of tile t: (filled, direction, area, network summary)."""

def flow_phase6(layout: Layout, summaries: List[bytes]) -> List[bytes]:
    """Phase 6: every tile's network levels."""

def flow_phase7(
    layout: Layout, t: int, routed: bytes, inflow: bytes, net: bytes, input: bytes, channel_area: float
) -> Tuple[F32, F32, F32, bytes]:
    """Phase 7 of tile t: (strahler, watersheds, hand, network)."""

def flow_assemble(layout: Layout, geo: Geo, networks: List[bytes]) -> Tuple[str, str]:
    """The channel network (GeoJSON text) and the figures (JSON text)."""

# The passes of the tiled masks (relief.dask.masks): settings as JSON keyword arguments.
def masks_check(settings_json: str) -> None:
    """Checks the masks settings (an error names the field)."""

def masks_counts(layout: Layout, t: int, input: bytes) -> bytes:
    """First count of tile t's heights and |profile curvature| (high 16 bits of the keys)."""

def masks_targets(settings_json: str, counts: List[bytes]) -> bytes:
    """The bins and ranks of the map's height bands and curvature scale."""

def masks_fine(layout: Layout, t: int, input: bytes, targets: bytes) -> bytes:
    """Second count of tile t, within the target bins."""

def masks_scales(targets: bytes, fine: List[bytes]) -> str:
    """The map's height bands and curvature scale (MaskScales as JSON)."""

def masks_tile(
    layout: Layout, t: int, input: bytes, routed: bytes, inflow: bytes, hand: F32, settings_json: str,
    scales_json: str
) -> Tuple[Dict[str, F32], F32]:
    """Tile t's masks by name and its splat weights (rows, columns x 4)."""
