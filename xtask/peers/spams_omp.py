"""SPAMS `omp` peer of the Batch-OMP benchmarks (relief-sparse-core, `benches/benches/omp.rs`).

Usage: python spams_omp.py DATA_DIR [THREADS]
Reads DATA_DIR/omp_k{K}_n{N}_{dict,signals}.npy (written by `cargo bench -p relief-benches
--bench omp` from the same real terrain patches the criterion bench codes: one unit-norm atom /
one signal per row, float32) and codes them with `spams.omp` (L = s, numThreads = THREADS,
default 2), in float32 and in float64 (the bench times both precisions on the same patches).

Prints one JSON object on stdout, per case (e.g. k64_n256_s1):
  "k64_n256_s1_s"       median seconds of 3 valid float32 runs after one warm-up (the
                        dashboard's peer time for omp/batch_omp_f32/...; see the float32 note),
  "f64_k64_n256_s1_s"   the same in float64 (peer time for omp/batch_omp_f64/...),
  "k64_n256_s1"         float32 signals per second, "cpu_k64_n256_s1" float32 signals per
                        CPU-second of the process (comparable when the machine is shared),
  "k64_n256_s1_f32_fell_back_to_f64"  1 when spams' float32 path failed and the float64 time
                        stands in for it (0 otherwise).
"""

import json
import sys
import time

import numpy as np
import spams

CASES = [(64, 256, 1), (64, 256, 4), (64, 256, 8), (256, 1024, 8)]


def aligned_fortran(a, dtype, align=64):
    """A Fortran-order copy of `a` whose data starts on an `align`-byte boundary."""
    a = np.asarray(a, dtype=dtype)
    nbytes = a.size * a.itemsize
    buf = np.empty(nbytes + align, dtype=np.uint8)
    off = (-buf.ctypes.data) % align
    out = buf[off:off + nbytes].view(dtype).reshape(a.shape, order="F")
    out[...] = a
    return out


def timed_runs(X, D, s, threads, n_signals, max_attempts=6):
    """Median wall and CPU seconds of 3 valid runs (after one warm-up), or None.

    spams-bin's float32 path sometimes returns all-zero codes (observed on these inputs), which
    would time as absurdly fast: runs whose codes hold fewer than 90 % of the n * s coefficients
    are discarded; after `max_attempts` attempts without 3 valid runs the case has failed.
    """
    spams.omp(X[:, :1024], D, L=s, numThreads=threads)
    times, cpu = [], []
    for _ in range(max_attempts):
        t0, c0 = time.perf_counter(), time.process_time()
        a = spams.omp(X, D, L=s, numThreads=threads)
        dt, dc = time.perf_counter() - t0, time.process_time() - c0
        if a.nnz >= 0.9 * s * n_signals:
            times.append(dt)
            cpu.append(dc)
        if len(times) == 3:
            return float(np.median(times)), float(np.median(cpu))
    return None


def main():
    data = sys.argv[1]
    threads = int(sys.argv[2]) if len(sys.argv) > 2 else 2
    out = {}
    for k, n, s in CASES:
        d = np.load(f"{data}/omp_k{k}_n{n}_dict.npy").astype(np.float32)
        x = np.load(f"{data}/omp_k{k}_n{n}_signals.npy").astype(np.float32)
        m = x.shape[0]
        key = f"k{k}_n{n}_s{s}"
        # SPAMS wants one atom / one signal per column, Fortran order. Its float32 path returned
        # all-zero codes on some runs with numpy's default placement of the arrays; 64-byte
        # aligned copies avoid it (and the runs are checked anyway).
        D32, X32 = aligned_fortran(d.T, np.float32), aligned_fortran(x.T, np.float32)
        r32 = timed_runs(X32, D32, s, threads, m)
        D64, X64 = aligned_fortran(d.T, np.float64), aligned_fortran(x.T, np.float64)
        r64 = timed_runs(X64, D64, s, threads, m)
        if r64:
            out[f"f64_{key}_s"] = r64[0]
        fell_back = r32 is None
        if fell_back:
            r32 = r64
        if r32:
            out[f"{key}_s"] = r32[0]
            out[key] = m / r32[0]
            out[f"cpu_{key}"] = m / r32[1]
        out[f"{key}_f32_fell_back_to_f64"] = 1 if fell_back else 0
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
