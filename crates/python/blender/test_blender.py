"""Headless test of the add-on: `blender -b --factory-startup --python test_blender.py --
RELIEF_DIR DEM EXEMPLAR`. RELIEF_DIR holds the installed `relief` package (Blender's own
numpy is used). Exits 1 on a failed check."""

import math
import sys
import traceback

argv = sys.argv[sys.argv.index("--") + 1:]
relief_dir, dem, exemplar = argv
sys.path.insert(0, relief_dir)


def main():
    import bpy
    import numpy as np

    sys.path.insert(0, __import__("os").path.dirname(__file__))
    import relief
    import relief_blender

    relief_blender.register()
    r = relief.read(dem)
    rows, cols = r.array.shape
    cx, cy = r.cell_size
    assert bpy.ops.relief.import_dem(filepath=dem) == {"FINISHED"}
    ob = bpy.context.active_object
    assert ob is not None and ob["relief_path"] == dem
    assert len(ob.data.vertices) == rows * cols and len(ob.data.polygons) == (rows - 1) * (cols - 1)
    co = np.empty(rows * cols * 3, np.float32)
    ob.data.vertices.foreach_get("co", co)
    co = co.reshape(rows, cols, 3)
    # Metres: the extent is the ground size, the heights the DEM's.
    assert math.isclose(co[0, -1, 0] - co[0, 0, 0], (cols - 1) * cx, rel_tol=1e-5), co[0, -1, 0]
    assert math.isclose(co[0, 0, 1] - co[-1, 0, 1], (rows - 1) * cy, rel_tol=1e-5), co[-1, 0, 1]
    assert np.array_equal(co[:, :, 2], r.array), "heights differ from the DEM"
    assert tuple(ob["relief_transform"]) == tuple(r.transform)[:6]

    scene = bpy.context.scene
    scene.relief.exemplar = exemplar
    scene.relief.factor = "4"
    scene.relief.seed = 1
    assert bpy.ops.relief.amplify() == {"FINISHED"}
    amp = bpy.context.active_object
    assert amp is not ob and len(amp.data.vertices) == 16 * rows * cols
    want = relief.amplify(r, exemplar, 4, seed=1)
    co = np.empty(len(amp.data.vertices) * 3, np.float32)
    amp.data.vertices.foreach_get("co", co)
    assert np.array_equal(co.reshape(4 * rows, 4 * cols, 3)[:, :, 2], want.array), "amplified heights differ"
    assert math.isclose(amp["relief_cell"][0], cx / 4, rel_tol=1e-9)

    bpy.context.view_layer.objects.active = ob
    scene.relief.mesh_cells = 48
    assert bpy.ops.relief.volume() == {"FINISHED"}
    vol = [o for o in bpy.data.objects if o.name.endswith(" arches")][0]
    assert len(vol.data.polygons) > 100
    # The strata's colours arrive as a colour attribute shown by the mesh's material.
    attr = vol.data.color_attributes["relief_rock"]
    assert len(attr.data) == len(vol.data.vertices)
    reds = [attr.data[i].color[0] for i in range(0, len(attr.data), 97)]
    assert max(reds) > 0.05 and len(set(round(r, 3) for r in reds)) > 3
    assert vol.data.materials[0].name.startswith("relief rock")
    relief_blender.unregister()
    print(f"blender add-on: ok (import {rows}x{cols}, amplify x4, volume {len(vol.data.polygons)} triangles)")


try:
    main()
except Exception:
    traceback.print_exc()
    sys.exit(1)
