#!/usr/bin/env python3
"""Times PyWavelets' 2-D multi-level DWT (wavedec2 + waverec2) as the peer of relief-wavelet-lod's
lifting transform.

Usage: pywt_dwt.py [SIZE] [LEVELS] [WAVELET] [REPEATS]
(defaults 4096 6 bior2.2 3). Data: float32 random walk surface (the dtype relief uses); mode
'symmetric' (PyWavelets' default). Prints one JSON line with the best-of-REPEATS seconds of
wavedec2, waverec2 and their sum, and the max reconstruction error.
"""
import json
import sys
import time

import numpy as np
import pywt

size = int(sys.argv[1]) if len(sys.argv) > 1 else 4096
levels = int(sys.argv[2]) if len(sys.argv) > 2 else 6
wavelet = sys.argv[3] if len(sys.argv) > 3 else "bior2.2"
repeats = int(sys.argv[4]) if len(sys.argv) > 4 else 3

rng = np.random.default_rng(1)
x = np.cumsum(np.cumsum(rng.standard_normal((size, size), dtype=np.float32), axis=0), axis=1)
x = x.astype(np.float32)

best_dec, best_rec, err = float("inf"), float("inf"), 0.0
for _ in range(repeats):
    t0 = time.perf_counter()
    coeffs = pywt.wavedec2(x, wavelet, mode="symmetric", level=levels)
    t1 = time.perf_counter()
    y = pywt.waverec2(coeffs, wavelet, mode="symmetric")
    t2 = time.perf_counter()
    best_dec = min(best_dec, t1 - t0)
    best_rec = min(best_rec, t2 - t1)
    err = float(np.abs(y[:size, :size] - x).max())
print(json.dumps(dict(peer="pywt", pywt_version=pywt.__version__, size=size, levels=levels,
                      wavelet=wavelet, dtype=str(x.dtype), wavedec2_s=best_dec,
                      waverec2_s=best_rec, total_s=best_dec + best_rec, max_error=err)))
