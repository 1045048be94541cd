"""SPAMS `omp` peer of the Batch-OMP benchmarks (relief-sparse-core, `benches/benches/omp.rs`).

Usage: python spams_omp.py DATA_DIR [THREADS]
Reads DATA_DIR/omp_k{K}_n{N}_{dict,signals}.npy (written by `cargo bench -p relief-benches
--bench omp` from the same real terrain patches the criterion bench codes: one unit-norm atom /
one signal per row, float32) and codes them with `spams.omp` (L = s, numThreads = THREADS,
default 2). Prints one JSON object {"k64_n256_s1": signals per second, ...} on stdout (median of
3 runs after one warm-up), plus "cpu_k64_n256_s1": signals per CPU-second of the process (a
figure that stays comparable when the machine is shared).
"""

import json
import sys
import time

import numpy as np
import spams

CASES = [(64, 256, 1), (64, 256, 4), (64, 256, 8), (256, 1024, 8)]


def main():
    data = sys.argv[1]
    threads = int(sys.argv[2]) if len(sys.argv) > 2 else 2
    out = {}
    for k, n, s in CASES:
        d = np.load(f"{data}/omp_k{k}_n{n}_dict.npy").astype(np.float32)
        x = np.load(f"{data}/omp_k{k}_n{n}_signals.npy").astype(np.float32)
        # SPAMS wants one atom / one signal per column, Fortran order.
        D = np.asfortranarray(d.T)
        X = np.asfortranarray(x.T)
        spams.omp(X[:, :1024], D, L=s, numThreads=threads)
        times = []
        cpu = []
        for _ in range(3):
            t0, c0 = time.perf_counter(), time.process_time()
            spams.omp(X, D, L=s, numThreads=threads)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        out[f"k{k}_n{n}_s{s}"] = x.shape[0] / float(np.median(times))
        out[f"cpu_k{k}_n{n}_s{s}"] = x.shape[0] / float(np.median(cpu))
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
