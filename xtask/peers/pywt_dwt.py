"""PyWavelets peer of the DWT benchmark (relief-wavelet-lod, `benches/benches/dwt.rs`,
criterion id `wavelet_lod/dwt_fwd_inv_cdf53/4096`).

Usage: python pywt_dwt.py DATA_DIR [REPEATS]
Reads DATA_DIR/dwt_surface_4096.npy: the float32 random-walk surface the criterion bench
transforms, written by `cargo xtask bench` with the same construction and generator. Times
`pywt.wavedec2` + `pywt.waverec2` with `bior2.2` (the CDF 5/3 biorthogonal pair), mode
'symmetric', 6 levels, on it (one warm-up, then the median of REPEATS runs, default 3).
Prints one JSON object on stdout: "dwt_fwd_inv_bior22_4096_s" (the dashboard's peer time),
"wavedec2_4096_s", "waverec2_4096_s" and "max_error" (reconstruction, metres).
"""

import json
import sys
import time

import numpy as np
import pywt

LEVELS = 6
WAVELET = "bior2.2"


def main():
    data = sys.argv[1]
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    x = np.load(f"{data}/dwt_surface_4096.npy").astype(np.float32)
    size = x.shape[0]
    coeffs = pywt.wavedec2(x, WAVELET, mode="symmetric", level=LEVELS)
    pywt.waverec2(coeffs, WAVELET, mode="symmetric")
    dec, rec, total = [], [], []
    err = 0.0
    for _ in range(repeats):
        t0 = time.perf_counter()
        coeffs = pywt.wavedec2(x, WAVELET, mode="symmetric", level=LEVELS)
        t1 = time.perf_counter()
        y = pywt.waverec2(coeffs, WAVELET, mode="symmetric")
        t2 = time.perf_counter()
        dec.append(t1 - t0)
        rec.append(t2 - t1)
        total.append(t2 - t0)
        err = float(np.abs(y[:size, :size] - x).max())
    out = {
        f"dwt_fwd_inv_bior22_{size}_s": float(np.median(total)),
        f"wavedec2_{size}_s": float(np.median(dec)),
        f"waverec2_{size}_s": float(np.median(rec)),
        "max_error": err,
        "dtype": str(coeffs[0].dtype),
        "pywt_version": pywt.__version__,
    }
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
