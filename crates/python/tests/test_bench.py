"""Python call overhead for amplify x16 of a grandcanyon crop (the same bytes as the `relief`
binary): the wall time of `relief.read` + `relief.amplify` + `relief.write` against `relief
amplify` writing the same .npy (medians of interleaved runs, printed), and the Python layer of
the call (its wall time minus the library job's own, `_relief.last_run_seconds`), asserted
under 5 % of the call. The CLI comparison also compares two builds of the library (the wheel's
and the binary's, e.g. a dev wheel and a test-profile binary): build both with the same profile
to read it. Timing needs a quiet machine: the row runs with RELIEF_BENCH=1 (RELIEF_BENCH_SIZE
sets the crop side, default 128: a 2048 x 2048 output; RELIEF_BIN the binary)."""

from __future__ import annotations

import os
import statistics
import subprocess
import time

import numpy as np
import pytest

import relief
from conftest import FIXTURE


@pytest.mark.skipif(os.environ.get("RELIEF_BENCH") != "1", reason="timing row: set RELIEF_BENCH=1")
def test_python_overhead_of_amplify_x16(relief_bin, tmp_path):
    n = int(os.environ.get("RELIEF_BENCH_SIZE", "128"))
    r = relief.read(FIXTURE)
    crop = tmp_path / "crop.tif"
    relief.write(crop, relief.Raster(r.array[:n, :n].copy(), r.transform, r.crs, r.cell_size, georef=r.georef))
    cli_s, py_s, lib_s = [], [], []
    for i in range(5):
        out = tmp_path / f"cli{i}.npy"
        t = time.perf_counter()
        subprocess.run([str(relief_bin), "amplify", str(crop), str(out), "--exemplar", str(FIXTURE),
                        "--factor", "16", "--seed", "1"], check=True, capture_output=True)
        cli_s.append(time.perf_counter() - t)
        t = time.perf_counter()
        src = relief.read(crop)
        t1 = time.perf_counter()
        a = relief.amplify(src, FIXTURE, 16, seed=1)
        call = time.perf_counter() - t1
        lib_s.append(relief._relief.last_run_seconds())
        relief.write(tmp_path / f"py{i}.npy", a)
        py_s.append(time.perf_counter() - t)
        # The Python layer of the call: arguments, settings, the job's thread, the polling,
        # the result's array (the rest is the library's work).
        assert call - lib_s[-1] < 0.05 * call, (call, lib_s[-1])
        assert np.array_equal(np.load(out).view(np.uint32), a.array.view(np.uint32))
    c, p, lib = statistics.median(cli_s), statistics.median(py_s), statistics.median(lib_s)
    print(f"\namplify x16 of a {n}x{n} grandcanyon crop ({16 * n}x{16 * n} out): cli {c:.2f} s, "
          f"python {p:.2f} s ({100 * (p - c) / c:+.1f} %), of which the library's job {lib:.2f} s "
          f"(runs cli {cli_s}, python {py_s}, job {lib_s})")
