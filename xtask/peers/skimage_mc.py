"""scikit-image `marching_cubes` peer of the meshing benchmark (relief-implicit-volume,
`benches/benches/volume.rs`, criterion id
`implicit_volume/marching_tetrahedra_precomputed_2threads/256`).

Usage: python skimage_mc.py DATA_DIR
Reads DATA_DIR/volume256.npy: the 256^3 float32 sampling of the karst + sea scene (numpy order
(z, y, x)) that the criterion bench meshes, and times `marching_cubes(vol, level=0.5)` (the
field threshold) on it: one warm-up, then the median of 3 runs. Prints one JSON object on
stdout: "marching_cubes_256_s" (the dashboard's peer time), "vertices", "triangles".
"""

import json
import sys
import time

import numpy as np
from skimage.measure import marching_cubes


def main():
    data = sys.argv[1]
    vol = np.load(f"{data}/volume256.npy")
    marching_cubes(vol, level=0.5)
    times = []
    for _ in range(3):
        t = time.perf_counter()
        verts, faces, _normals, _values = marching_cubes(vol, level=0.5)
        times.append(time.perf_counter() - t)
    out = {
        f"marching_cubes_{vol.shape[0]}_s": float(np.median(times)),
        "vertices": len(verts),
        "triangles": len(faces),
    }
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
