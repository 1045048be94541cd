#!/usr/bin/env python3
"""The landform protocol of issue 41 through the CLI, measured by the reference tool.

  python xtask/peers/landform_check.py [--relief target/release/relief] [--out DIR]
         [--methods amplify,refine] [--factors 4,16] [--dems alps_dem,...] [--extra ARGS]

For alps_dem, N47E011 (voids filled), carrizo and grandcanyon: a truth crop and an exemplar
from a disjoint part of the same DEM (the crops of the amplification protocol), the truth box
down-sampled xF, rebuilt with the CLI's default flags (`relief amplify` / `relief refine`, plus
`--extra`), and compared with the truth by `../shared/tools/terrain_quality.py`. Prints one
block per case and a summary table with the issue's drainage bars: pits/km2 <= 2x truth's,
fill depth <= 2x truth's + 0.05 m, |beta - truth's| <= 0.06; and the grid measure within 0.1;
and scratches (one-cell-wide troughs, `scratches`) per million cells beside the truth's.
Writes every truth/output as .npy under --out (default target/landform) to look at.
Needs numpy and scipy (the peers venv: target/peers-venv/bin/python).
"""
import argparse, json, os, re, subprocess, sys
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DEM = os.path.join(ROOT, "..", "shared", "data", "dem")
TQ = os.path.join(ROOT, "..", "shared", "tools", "terrain_quality.py")
# (id, truth x, y, w, h, exemplar x, y, w, h): the crops of amplify_quality.rs.
CASES = {
    "alps_dem": ((100, 200, 512, 512), (1300, 100, 1024, 640)),
    "N47E011": ((0, 688, 512, 512), (600, 688, 601, 512)),
    "carrizo": ((0, 0, 448, 448), (0, 452, 505, 448)),
    "grandcanyon": ((0, 0, 256, 512), (256, 0, 256, 512)),
}


def load(dem):
    meta = json.load(open(os.path.join(DEM, dem + ".json")))
    a = np.fromfile(os.path.join(DEM, meta["data_file"]), "<f4").reshape(meta["height"], meta["width"])
    nd = meta.get("nodata")
    a = a.astype(np.float64)
    if nd is not None:
        a[a == nd] = np.nan
    cx = meta.get("cell_size_x_m", meta["cell_size_m"])
    cy = meta.get("cell_size_y_m", meta["cell_size_m"])
    return a, cx, cy


def fill_voids(a):
    """Nearest-valid then smoothing fill, only for N47E011's few voids in the crops."""
    if not np.isnan(a).any():
        return a
    from scipy import ndimage
    m = np.isnan(a)
    idx = ndimage.distance_transform_edt(m, return_distances=False, return_indices=True)
    b = a[tuple(idx)]
    for _ in range(50):
        s = ndimage.uniform_filter(b, 3)
        b[m] = s[m]
    return b


def boxdown(a, f):
    h, w = a.shape
    return a[: h // f * f, : w // f * f].reshape(h // f, f, w // f, f).mean((1, 3))


def scratches(z):
    """One-cell-wide troughs or ridges per million cells: runs of at least 6 cells along a row or
    column that stand more than 3 median steps off the mean of their two neighbours across,
    which agree with each other (a breach cut or a filled trench one cell wide reads as a
    scratch in a hillshade). Real DEMs: 0-11; a valley a few cells wide does not count."""
    z = z.astype(np.float64)
    med = np.median(np.abs(np.diff(z, axis=0)))
    thr = 3 * med
    n = 0
    for a in (z, z.T):
        off = a[1:-1, :] - 0.5 * (a[:-2, :] + a[2:, :])
        m = (np.abs(off) > thr) & (np.abs(a[:-2, :] - a[2:, :]) < thr / 2)
        for row in m:
            r = 0
            for v in row:
                r = r + 1 if v else 0
                n += r == 6
    return n / z.size * 1e6


def save(path, a):
    np.save(path, a.astype(np.float32))


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"failed: {' '.join(cmd)}\n{r.stderr}")
    return r.stdout


def parse(txt):
    nums = {}
    for who in ("truth", "output", "baseline"):
        m = re.search(who + r":(.*?)(?=\n\S|\Z)", txt, re.S)
        if not m:
            continue
        block = m.group(1)
        for k in ("consistency", "dslope", "slope_emd", "curv_emd", "grid", "pits/km2", "fill", "beta"):
            mm = re.search(re.escape(k) + r" ([-+0-9.naninf]+)", block)
            if mm:
                nums[(who, k)] = float(mm.group(1))
    return nums


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--relief", default=os.path.join(ROOT, "target", "release", "relief"))
    p.add_argument("--out", default=os.path.join(ROOT, "target", "landform"))
    p.add_argument("--methods", default="amplify,refine")
    p.add_argument("--factors", default="4,16")
    p.add_argument("--dems", default=",".join(CASES))
    p.add_argument("--extra", default="", help="extra flags for every run")
    p.add_argument("--tag", default="default")
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)
    rows = []
    for dem in a.dems.split(","):
        full, cx, cy = load(dem)
        (tx, ty, tw, th), (ex, ey, ew, eh) = CASES[dem]
        truth = fill_voids(full[ty : ty + th, tx : tx + tw].copy())
        exem = fill_voids(full[ey : ey + eh, ex : ex + ew].copy())
        cell = (cx * cy) ** 0.5
        tpath = os.path.join(a.out, f"{dem}_truth.npy")
        epath = os.path.join(a.out, f"{dem}_exemplar.npy")
        save(tpath, truth)
        save(epath, exem)
        for f in map(int, a.factors.split(",")):
            cpath = os.path.join(a.out, f"{dem}_x{f}_input.npy")
            save(cpath, boxdown(truth, f))
            for method in a.methods.split(","):
                opath = os.path.join(a.out, f"{dem}_x{f}_{method}_{a.tag}.npy")
                cs = f"{cx * f},{cy * f}"
                if method == "amplify":
                    cmd = [a.relief, "amplify", cpath, opath, "--exemplar", epath, "--factor", str(f),
                           "--cell-size", cs, "--exemplar-cell-size", f"{cx},{cy}"]
                elif method == "refine":
                    cmd = [a.relief, "refine", cpath, opath, "--levels", str(int(round(np.log2(f)))),
                           "--cell-size", cs]
                else:
                    sys.exit(f"unknown method {method}")
                cmd += ["--force", "-q"] + a.extra.split()
                run(cmd)
                out = run([sys.executable, TQ, tpath, opath, str(f), str(cell)])
                print(f"## {dem} x{f} {method} ({a.tag})\n{out}", flush=True)
                nums = parse(out)
                nums[("output", "scratches")] = scratches(np.load(opath)[:th, :tw])
                nums[("truth", "scratches")] = scratches(truth)
                rows.append((dem, f, method, nums))
    print("\n| case | pits/km2 out (truth) | fill m out (truth) | beta out (truth) | grid out (truth) | consist | dslope | scratches/Mcell out (truth) | bars |")
    print("|---|---|---|---|---|---|---|---|---|")
    for dem, f, method, n in rows:
        g = lambda w, k: n.get((w, k), float("nan"))
        ok_p = g("output", "pits/km2") <= 2 * g("truth", "pits/km2")
        ok_f = g("output", "fill") <= 2 * g("truth", "fill") + 0.05
        ok_b = abs(g("output", "beta") - g("truth", "beta")) <= 0.06
        print(f"| {dem} x{f} {method} | {g('output', 'pits/km2'):.2f} ({g('truth', 'pits/km2'):.2f}) | "
              f"{g('output', 'fill'):.3f} ({g('truth', 'fill'):.3f}) | {g('output', 'beta'):.3f} ({g('truth', 'beta'):.3f}) | "
              f"{g('output', 'grid'):.2f} | {100 * g('output', 'consistency'):.2f}% | {g('output', 'dslope'):.2f} | "
              f"{g('output', 'scratches'):.0f} ({g('truth', 'scratches'):.0f}) | "
              f"{'P' if ok_p else 'p'}{'F' if ok_f else 'f'}{'B' if ok_b else 'b'} |")


if __name__ == "__main__":
    main()
