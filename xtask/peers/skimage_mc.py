"""Times scikit-image marching_cubes on the grid written by the release example
`cargo run --release -p relief-implicit-volume --example bench_volume`
(target/bench-data/volume256.npy, float32, shape (z, y, x), iso-value 0.5).

Run with: /work/main/target/peers-venv/bin/python xtask/peers/skimage_mc.py [path]
"""
import sys
import time
from pathlib import Path

import numpy as np
from skimage.measure import marching_cubes


def main() -> None:
    root = Path(__file__).resolve().parents[2]
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else root / "target/bench-data/volume256.npy"
    vol = np.load(path)
    best = float("inf")
    for _ in range(3):
        t = time.perf_counter()
        verts, faces, _normals, _values = marching_cubes(vol, level=0.5)
        best = min(best, time.perf_counter() - t)
    print(f"skimage marching_cubes on {vol.shape}: {best:.3f} s (best of 3), "
          f"{len(verts)} vertices, {len(faces)} triangles")


if __name__ == "__main__":
    main()
