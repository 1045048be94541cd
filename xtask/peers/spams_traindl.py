"""SPAMS `trainDL` peer of the K-SVD benchmark (relief-dictionary-learning,
`crates/dictionary-learning/examples/bench_ksvd.rs`).

Usage: python spams_traindl.py PATCHES.npy|DATA_DIR [THREADS] [EPOCHS...]
Reads the float32 patch matrix written by the example (one mean-removed 16x16 patch per row;
given a folder, DATA_DIR/ksvd_patches.npy, as `cargo xtask bench` does),
learns N = 256 atoms with `spams.trainDL` (online dictionary learning, Mairal et al. 2010,
mode 2 = lasso + ridge, lambda = 1.2 / sqrt(K) x median patch norm, batch size 512, numThreads = THREADS, default 2) for each number of
epochs given (default 1 and 3), and measures the representation error of every learned
dictionary the same way the Rust side does: OMP with s = 4 (`spams.omp`, L = 4), RMSE per
coefficient. Prints one JSON object {"runs": [{"epochs", "seconds", "rmse"}, ...], "n", "k"} on
stdout, plus flat keys for the dashboard: "traindl_<E>ep_s" (seconds) and "traindl_<E>ep_rmse"
for each number of epochs E (e.g. "traindl_3ep_s").
"""

import json
import os
import sys
import time

import numpy as np
import spams


def main():
    path = sys.argv[1]
    if os.path.isdir(path):
        path = os.path.join(path, "ksvd_patches.npy")
    threads = int(sys.argv[2]) if len(sys.argv) > 2 else 2
    epochs_list = [float(e) for e in sys.argv[3:]] or [1.0, 3.0]
    x = np.load(path).astype(np.float32)
    n, k = x.shape
    X = np.asfortranarray(x.T)
    norms = np.linalg.norm(x, axis=1)
    # SPAMS' usual lambda = 1.2 / sqrt(m) for unit-norm signals, scaled to the typical patch
    # norm (patches are in metres).
    lam = 1.2 / np.sqrt(k) * float(np.median(norms))
    batch = 512
    runs = []
    for epochs in epochs_list:
        it = max(1, int(round(epochs * n / batch)))
        t0 = time.perf_counter()
        D = spams.trainDL(X, K=256, lambda1=lam, mode=2, iter=it, batchsize=batch,
                          numThreads=threads, verbose=False)
        secs = time.perf_counter() - t0
        D = np.asfortranarray(D / np.maximum(np.linalg.norm(D, axis=0), 1e-12))
        A = spams.omp(X, D, L=4, numThreads=threads)
        r = X.astype(np.float64) - D.astype(np.float64) @ A.toarray()
        rmse = float(np.sqrt(np.mean(r * r)))
        runs.append({"epochs": epochs, "seconds": secs, "rmse": rmse})
    out = {"runs": runs, "n": n, "k": k}
    for r in runs:
        tag = f"{r['epochs']:g}ep"
        out[f"traindl_{tag}_s"] = r["seconds"]
        out[f"traindl_{tag}_rmse"] = r["rmse"]
    json.dump(out, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
