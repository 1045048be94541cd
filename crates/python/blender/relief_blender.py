"""relief for Blender: import a DEM (any raster relief reads, or a relief output) as a mesh in
metres, and amplify, refine or mesh in 3-D (``relief.volume``) the active terrain from a panel
(3D View > Sidebar > Relief).

Install: the ``relief`` Python package must be importable by Blender's Python (``pip install
--target <blender scripts>/modules ./crates/python``, or a folder holding it added to
``sys.path``); then Edit > Preferences > Add-ons > Install... this file.

The grid is placed in metres: cell ``(row, col)`` at ``x = col * cx``, ``y = -row * cy`` (+Y
north, the object's origin on the north-west cell), ``z`` the elevation, with ``cx, cy`` the
ground cell size relief derives (so slopes are true, also for geographic and Web Mercator
grids). The georeference (rasterio-style affine transform, CRS WKT, relief's own GeoRef) and the
source file are kept as custom properties of the object (``relief_transform``, ``relief_crs``,
``relief_georef``, ``relief_path``, ``relief_cell``). Rasters above 2^20 cells are meshed every
k-th cell (``relief_step``); the jobs always read the full-resolution source.
"""

from __future__ import annotations

import os

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

import relief

bl_info = {
    "name": "relief terrain",
    "author": "relief",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "File > Import > relief DEM; 3D View > Sidebar > Relief",
    "description": "Import DEMs as meshes in metres; amplify, refine and volume with relief",
    "category": "Import-Export",
}

# Largest grid turned into a mesh; larger rasters are subsampled (every k-th cell).
MAX_MESH_CELLS = 1 << 20


def polygon_mesh(name: str, co: np.ndarray, corners: np.ndarray, k: int) -> bpy.types.Mesh:
    """A mesh of the vertices ``co`` (x, y, z flat) and polygons of ``k`` corners each, their
    vertex indices flat in ``corners``."""
    n = len(corners) // k
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(co) // 3)
    me.vertices.foreach_set("co", co)
    me.loops.add(k * n)
    me.loops.foreach_set("vertex_index", corners)
    me.polygons.add(n)
    me.polygons.foreach_set("loop_start", np.arange(0, k * n, k, dtype=np.int32))
    me.polygons.foreach_set("loop_total", np.full(n, k, dtype=np.int32))
    me.update(calc_edges=True)
    return me


def grid_mesh(name: str, z: np.ndarray, cell: tuple, step: int = 1) -> bpy.types.Mesh:
    """A mesh of the grid ``z`` (rows north to south) with cells ``cell`` metres, every
    ``step``-th sample, in metres (voids dropped as holes at 0 m would lie: they become the
    grid's lowest value)."""
    z = np.asarray(z, dtype=np.float32)[::step, ::step]
    if not np.isfinite(z).all():
        z = np.where(np.isfinite(z), z, np.nanmin(z))
    rows, cols = z.shape
    cx, cy = cell[0] * step, cell[1] * step
    xs, ys = np.meshgrid(np.arange(cols, dtype=np.float32) * cx, -np.arange(rows, dtype=np.float32) * cy)
    co = np.stack([xs, ys, z], axis=-1).reshape(-1)
    i = np.arange(rows * cols, dtype=np.int32).reshape(rows, cols)
    quads = np.stack([i[:-1, :-1], i[1:, :-1], i[1:, 1:], i[:-1, 1:]], axis=-1).reshape(-1)
    me = polygon_mesh(name, co, quads, 4)
    me.validate()
    return me


def mesh_step(shape: tuple) -> int:
    cells = shape[0] * shape[1]
    step = 1
    while cells // (step * step) > MAX_MESH_CELLS:
        step += 1
    return step


def add_terrain(context, name: str, r: "relief.Raster", path: str = "") -> bpy.types.Object:
    """Links a terrain object for raster ``r`` and records its georeference."""
    step = mesh_step(r.array.shape)
    me = grid_mesh(name, r.array, r.cell_size, step)
    ob = bpy.data.objects.new(name, me)
    context.collection.objects.link(ob)
    ob["relief_path"] = path
    ob["relief_cell"] = list(r.cell_size)
    ob["relief_step"] = step
    ob["relief_shape"] = list(r.array.shape)
    if r.transform is not None:
        ob["relief_transform"] = [float(v) for v in tuple(r.transform)[:6]]
    if r.crs is not None:
        ob["relief_crs"] = str(r.crs)
    if r.georef is not None:
        ob["relief_georef"] = r.georef
    context.view_layer.objects.active = ob
    ob.select_set(True)
    return ob


def raster_of(ob: bpy.types.Object) -> "relief.Raster":
    """The full-resolution raster behind a terrain object (its source file), else the mesh's
    grid as sampled."""
    path = ob.get("relief_path", "")
    if path and os.path.exists(path):
        return relief.read(path)
    rows, cols = (int(v) for v in ob["relief_shape"])
    step = int(ob.get("relief_step", 1))
    rows, cols = len(range(0, rows, step)), len(range(0, cols, step))
    co = np.empty(len(ob.data.vertices) * 3, dtype=np.float32)
    ob.data.vertices.foreach_get("co", co)
    z = co.reshape(rows, cols, 3)[:, :, 2].copy()
    cell = tuple(float(v) * step for v in ob["relief_cell"])
    t = ob.get("relief_transform")
    return relief.Raster(z, transform=None if t is None else tuple(t), crs=ob.get("relief_crs"), cell_size=cell)


class RELIEF_OT_import_dem(bpy.types.Operator, ImportHelper):
    """Import a DEM (GeoTIFF, SRTM .hgt, ASCII grid, PNG, EXR, NPY, ...) as a mesh in metres"""

    bl_idname = "relief.import_dem"
    bl_label = "Import DEM (relief)"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(default="*.tif;*.tiff;*.hgt;*.asc;*.png;*.exr;*.npy;*.npz;*.f32;*.r16;*.r32", options={"HIDDEN"})

    def execute(self, context):
        try:
            r = relief.read(self.filepath)
        except (OSError, ValueError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        add_terrain(context, os.path.splitext(os.path.basename(self.filepath))[0], r, self.filepath)
        return {"FINISHED"}


class TerrainJob:
    """An operator running a relief job on the active terrain (an object this add-on made):
    ``run(s, ob)`` calls relief with the panel's settings ``s`` (an ``OSError`` or
    ``ValueError`` is reported and cancels), ``place(context, s, ob, out)`` adds its result."""

    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        s = context.scene.relief
        ob = context.active_object
        if ob is None or "relief_cell" not in ob:
            self.report({"ERROR"}, "the active object is not a relief terrain (import a DEM first)")
            return {"CANCELLED"}
        try:
            out = self.run(s, ob)
        except (OSError, ValueError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.place(context, s, ob, out)
        return {"FINISHED"}


class NewTerrainJob(TerrainJob):
    """A terrain job whose result is a raster: a new terrain object named ``ob.name`` and
    ``suffix(s)``, at the active terrain's place."""

    def place(self, context, s, ob, out):
        new = add_terrain(context, f"{ob.name} {self.suffix(s)}", out)
        new.location = ob.location


class RELIEF_OT_amplify(NewTerrainJob, bpy.types.Operator):
    """Amplify the active terrain with the exemplar's details (relief.amplify) into a new object"""

    bl_idname = "relief.amplify"
    bl_label = "Amplify"

    def run(self, s, ob):
        exemplar = bpy.path.abspath(s.exemplar) if s.exemplar else ob.get("relief_path", "")
        return relief.amplify(raster_of(ob), exemplar, int(s.factor), seed=s.seed, landform=s.landform)

    def suffix(self, s):
        return f"x{s.factor}"


class RELIEF_OT_refine(NewTerrainJob, bpy.types.Operator):
    """Refine the active terrain by wavelet synthesis (relief.refine) into a new object"""

    bl_idname = "relief.refine"
    bl_label = "Refine"

    def run(self, s, ob):
        return relief.refine(raster_of(ob), extra_levels=s.levels, seed=s.seed, landform=s.landform)

    def suffix(self, s):
        return "refined"


def add_rock_colours(me, colours):
    """The volume's vertex colours (sRGB bytes) as the colour attribute "relief_rock" (linear
    floats, as Blender stores them) and a material that shows it, as the GLB's COLOR_0 does."""
    srgb = colours[:, :3].astype(np.float64) / 255.0
    lin = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    rgba = np.concatenate([lin, colours[:, 3:4] / 255.0], axis=1).astype(np.float32)
    attr = me.color_attributes.new(name="relief_rock", type="FLOAT_COLOR", domain="POINT")
    attr.data.foreach_set("color", rgba.reshape(-1))
    mat = bpy.data.materials.new(name="relief rock")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    col = nodes.new("ShaderNodeVertexColor")
    col.layer_name = "relief_rock"
    mat.node_tree.links.new(col.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = 0.9
    me.materials.append(mat)


class RELIEF_OT_volume(TerrainJob, bpy.types.Operator):
    """Carve 3-D landforms into the active terrain (relief.volume) as a new mesh"""

    bl_idname = "relief.volume"
    bl_label = "Volume"

    def run(self, s, ob):
        return relief.volume(
            raster_of(ob), features=[s.feature], seed=s.seed, max_mesh_cells=s.mesh_cells, colours=True
        )

    def place(self, context, s, ob, out):
        v, f, c = out
        co = np.ascontiguousarray(v, dtype=np.float32).reshape(-1)
        me = polygon_mesh(f"{ob.name} {s.feature}", co, f.astype(np.int32).reshape(-1), 3)
        add_rock_colours(me, c)
        new = bpy.data.objects.new(me.name, me)
        context.collection.objects.link(new)
        # The volume mesh has y north from the south edge: put its north-west corner on the grid's.
        rows = int(ob["relief_shape"][0])
        new.location = ob.location
        new.location.y -= (rows - 1) * float(ob["relief_cell"][1])


class ReliefSettings(bpy.types.PropertyGroup):
    exemplar: StringProperty(name="Exemplar", subtype="FILE_PATH", description="Exemplar DEM (default: the terrain's own file)")
    factor: EnumProperty(name="Factor", items=[("4", "x4", ""), ("16", "x16", ""), ("64", "x64", "")], default="4")
    levels: IntProperty(name="Levels", default=relief.defaults("refine")["extra_levels"], min=1, max=12)
    seed: IntProperty(name="Seed", default=relief.defaults("amplify")["seed"], min=0)
    landform: BoolProperty(name="Landform pass", default=True)
    feature: EnumProperty(
        name="Feature",
        items=[(f, f, "") for f in ("arches", "karst", "hoodoos", "islands", "sea")],
        default="arches",
    )
    mesh_cells: IntProperty(name="Mesh cells", default=128, min=8, max=4096)


class RELIEF_PT_panel(bpy.types.Panel):
    bl_label = "Relief"
    bl_idname = "RELIEF_PT_panel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Relief"

    def draw(self, context):
        s = context.scene.relief
        col = self.layout.column()
        col.operator(RELIEF_OT_import_dem.bl_idname, text="Import DEM")
        col.separator()
        col.prop(s, "exemplar")
        col.prop(s, "factor")
        col.prop(s, "seed")
        col.prop(s, "landform")
        col.operator(RELIEF_OT_amplify.bl_idname)
        col.prop(s, "levels")
        col.operator(RELIEF_OT_refine.bl_idname)
        col.prop(s, "feature")
        col.prop(s, "mesh_cells")
        col.operator(RELIEF_OT_volume.bl_idname)
        ob = context.active_object
        if ob is not None and "relief_cell" in ob:
            cx, cy = ob["relief_cell"]
            col.label(text=f"cells {cx:.2f} x {cy:.2f} m, step {ob.get('relief_step', 1)}")


def menu_import(self, context):
    self.layout.operator(RELIEF_OT_import_dem.bl_idname, text="relief DEM (.tif, .hgt, .asc, ...)")


CLASSES = (ReliefSettings, RELIEF_OT_import_dem, RELIEF_OT_amplify, RELIEF_OT_refine, RELIEF_OT_volume, RELIEF_PT_panel)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.relief = bpy.props.PointerProperty(type=ReliefSettings)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    del bpy.types.Scene.relief
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)

