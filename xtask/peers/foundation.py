"""Peer timings for the foundation rows of the benchmark dashboard.

Usage: python foundation.py DATA_DIR
Reads DATA_DIR/grandcanyon_512.npy and grandcanyon_512_holes.npy (written by `cargo xtask
bench` from the same data the criterion benches use) and prints one JSON object
{"<key>_s": median seconds, ...} on stdout.
"""

import json
import sys
import time

import numpy as np
from skimage.restoration import inpaint_biharmonic
from skimage.transform import resize


def median_time(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main():
    data = sys.argv[1]
    dem = np.load(f"{data}/grandcanyon_512.npy").astype(np.float32)
    holes = np.load(f"{data}/grandcanyon_512_holes.npy").astype(np.float32)
    small = resize(dem, (128, 128), order=3, anti_aliasing=True, preserve_range=True)
    mask = np.isnan(holes)
    filled_in = np.where(mask, 0.0, holes).astype(np.float64)
    out = {
        "resize_aa_512_to_128_s": median_time(
            lambda: resize(dem, (128, 128), order=3, anti_aliasing=True, preserve_range=True), 7
        ),
        "resize_128_to_512_s": median_time(
            lambda: resize(small, (512, 512), order=3, preserve_range=True), 7
        ),
        "inpaint_biharmonic_512_s": median_time(lambda: inpaint_biharmonic(filled_in, mask), 3),
    }
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
