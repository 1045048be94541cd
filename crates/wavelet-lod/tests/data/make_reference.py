#!/usr/bin/env python3
"""Generates pywt_reference.json: PyWavelets coefficients for relief-wavelet-lod's fixture tests.

Run once (kept in the repository so the reference can be regenerated and audited):

    /work/main/target/peers-venv/bin/python crates/wavelet-lod/tests/data/make_reference.py

What is comparable. PyWavelets computes the DWT by convolution; its `symmetric` mode is a
half-sample extension and, like every non-periodic mode, returns floor((n + L - 1) / 2) coefficients
(more than the ceil(n/2) / floor(n/2) of a lifting transform). So the fixtures use:

1. `periodization` (exactly n/2 coefficients per lane) on even sizes, for all four bases (haar,
   bior2.2, bior4.4, db2): 1-D single level and 2-D multi-level `wavedec2`. relief's transform with
   `Boundary::Periodic` must give low = cA / sqrt(2) and high = -sqrt(2) cD per 1-D step (the
   "metric" normalisation), i.e. per 2-D level LL = cA / 2, H = -cH, V = -cV, D = 2 cD, and over
   several levels the approximation of depth k carries 1/2^k, details of depth k carry
   1/2^(k-1) (H, V: sign -1; D: factor 2).
2. Whole-sample symmetric boundaries (relief's `Boundary::Symmetric`) for the symmetric bases
   bior2.2 and bior4.4, on odd and even sizes: the signal is mirrored to period 2n - 2
   (x0 .. x_{n-1}, x_{n-2} .. x1) and transformed with `periodization`; the first ceil(n/2)
   low-pass and floor(n/2) high-pass coefficients of that equal the whole-sample symmetric
   transform of x. 1-D single level and 2-D single level (mirrored along both axes).

Inputs are float32 values (exactly representable in the Rust test); PyWavelets runs in float64.
"""
import json
import os

import numpy as np
import pywt

HERE = os.path.dirname(os.path.abspath(__file__))
rng = np.random.default_rng(20240501)


def f32(a):
    return np.asarray(a, dtype=np.float32).astype(np.float64)


def signal(n):
    # A random walk plus noise: terrain-like, not just white noise.
    return f32(np.cumsum(rng.standard_normal(n)) * 10.0 + rng.standard_normal(n))


def image(h, w):
    a = np.cumsum(np.cumsum(rng.standard_normal((h, w)), axis=0), axis=1)
    return f32(a + rng.standard_normal((h, w)) * 3.0)


def mirror1(x):
    return np.concatenate([x, x[-2:0:-1]])


def mirror2(a):
    a = np.concatenate([a, a[-2:0:-1, :]], axis=0)
    return np.concatenate([a, a[:, -2:0:-1]], axis=1)


cases = []
for wav in ["haar", "bior2.2", "bior4.4", "db2"]:
    x = signal(16)
    ca, cd = pywt.dwt(x, wav, mode="periodization")
    cases.append(dict(kind="dwt1", wavelet=wav, boundary="periodic", x=x.tolist(),
                      cA=ca.tolist(), cD=cd.tolist()))
    img = image(12, 16)  # height 12, width 16: even at depths 0 and 1
    coeffs = pywt.wavedec2(img, wav, mode="periodization", level=2)
    cases.append(dict(
        kind="wavedec2", wavelet=wav, boundary="periodic", width=16, height=12, levels=2,
        x=img.ravel().tolist(), cA=coeffs[0].ravel().tolist(),
        cA_shape=list(coeffs[0].shape),
        details=[dict(cH=c[0].ravel().tolist(), cV=c[1].ravel().tolist(),
                      cD=c[2].ravel().tolist(), shape=list(c[0].shape)) for c in coeffs[1:]],
    ))

for wav in ["bior2.2", "bior4.4"]:
    for n in [13, 14, 5]:
        x = signal(n)
        ca, cd = pywt.dwt(mirror1(x), wav, mode="periodization")
        cases.append(dict(kind="dwt1", wavelet=wav, boundary="symmetric", x=x.tolist(),
                          cA=ca[: (n + 1) // 2].tolist(), cD=cd[: n // 2].tolist()))
    for (h, w) in [(9, 11), (10, 7)]:
        img = image(h, w)
        ca, (ch, cv, cd) = pywt.dwt2(mirror2(img), wav, mode="periodization")
        hl, hh, wl, wh = (h + 1) // 2, h // 2, (w + 1) // 2, w // 2
        cases.append(dict(
            kind="wavedec2", wavelet=wav, boundary="symmetric", width=w, height=h, levels=1,
            x=img.ravel().tolist(), cA=ca[:hl, :wl].ravel().tolist(), cA_shape=[hl, wl],
            details=[dict(cH=ch[:hh, :wl].ravel().tolist(), cV=cv[:hl, :wh].ravel().tolist(),
                          cD=cd[:hh, :wh].ravel().tolist(), shape=[hh, wl])],
        ))

out = dict(generator="crates/wavelet-lod/tests/data/make_reference.py",
           pywt_version=pywt.__version__, numpy_version=np.__version__, cases=cases)
with open(os.path.join(HERE, "pywt_reference.json"), "w") as f:
    json.dump(out, f, separators=(",", ":"))
print(f"wrote {len(cases)} cases")
