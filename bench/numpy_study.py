#!/usr/bin/env python3
"""hoploc's simulation study (docs/design.md, section 9), written plainly in vectorised numpy, as the yardstick that
`hoploc simulate` is benchmarked against (bench target: Rust ≥ 20× faster, same tables within
Monte Carlo noise).

Same study and algorithms as loc-core's f64 reference:

* 10 m × 10 m area; anchors (0,0), (10,0), (10,10) [+ (0,10)]; agent at ((k+1)/2, (m+1)/2),
  k, m = 0…18 (361 points); `runs` runs per point; two channels with independent N(0, σ²) noise;
  log-normal model P0 = −40 dBm, α = 3 (known).
* Refinements: Ch1, Ch2, Max (largest z), Linear avg (mean in mW), Ext-MCH (every channel its own
  term in the MLE cost).
* MLE: coarse grid, step 1/COARSE of each side, then fine step 1/FINE within ± one coarse step
  of the coarse winner, inside the area; first minimum in x-major order wins. The divisions
  come from the command line (`--coarse-divs`, `--fine-divs`: the Rust bench passes
  loc-core's; 10 and 50 by default: 10 % and 2 % steps).
* MMSE: posterior mean over the full fine grid, weights exp(−cost / 2σ²).
* TRLT-3: linear system of the 3 circle equations; QUAD-4: mean of the four 3-anchor
  trilaterations; MDS: classical MDS of the (n+1)² distance matrix (anchor–anchor distances
  exact), top-2 eigenpairs, Procrustes fit (scale, rotation, reflection, translation) onto the
  anchors. Distances d̂ = 10^((P0 − z) / 10α). No clipping.
* Metrics: per-point RMSE over runs averaged over the points; bias = std over points of the
  per-point mean error, in x and in y.

Usage: python3 bench/numpy_study.py --runs 100 --sigma 2 4 --seed 1 [--coarse-divs 10]
       [--fine-divs 50] [--json out.json]
"""

import argparse
import json
import time

import numpy as np

P0, ALPHA = -40.0, 3.0
W = H = 10.0
ANCHORS4 = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
COLUMNS = ["Ch1", "Ch2", "Max", "Linear avg", "Ext-MCH"]


def points():
    v = (np.arange(19) + 1) / 2.0
    xx, yy = np.meshgrid(v, v, indexing="ij")
    return np.stack([xx.ravel(), yy.ravel()], axis=1)  # (361, 2)


def rssi(d):
    return P0 - 10.0 * ALPHA * np.log10(np.maximum(d, 0.01))


def refine(z, col):
    """z: (T, A, C) → (T, A) observations and the per-anchor weight (channels per term)."""
    if col == "Ch1":
        return z[..., 0], 1.0
    if col == "Ch2":
        return z[..., 1], 1.0
    if col == "Max":
        return z.max(axis=-1), 1.0
    if col == "Linear avg":
        return 10.0 * np.log10(np.mean(10.0 ** (z / 10.0), axis=-1)), 1.0
    # Ext-MCH: Σ_c (z_c − p)² = C·(mean_c z − p)² + const, so the dB mean with weight C.
    return z.mean(axis=-1), float(z.shape[-1])


# Lattice divisions per side (set from the command line in main).
FINE_DIVS = 50
COARSE_DIVS = 10


def lattice(anchors):
    """Mean RSSI from every anchor at every point of the fine lattice: (N·N, A), N = FINE_DIVS + 1.
    The coarse grid and every fine window lie on this lattice, so the model is evaluated once
    per anchor layout, as the Rust reference does."""
    n_fine = FINE_DIVS + 1
    f = np.arange(n_fine) / FINE_DIVS * W
    fx, fy = np.meshgrid(f, f, indexing="ij")
    grid = np.stack([fx.ravel(), fy.ravel()], axis=1)
    return grid, rssi(np.linalg.norm(grid[:, None, :] - anchors[None], axis=-1))


def costs_at(obs, w, table):
    """obs (T, A); table (G, A) shared or (T, G, A) per trial → weighted costs (T, G)."""
    if table.ndim == 2:
        table = table[None]
    return w * ((obs[:, None, :] - table) ** 2).sum(axis=-1)


def mle(obs, w, lat):
    grid, P = lat
    n_fine, ratio = FINE_DIVS + 1, FINE_DIVS // COARSE_DIVS
    c = np.arange(0, n_fine, ratio)
    ci, cj = np.meshgrid(c, c, indexing="ij")
    coarse = (ci * n_fine + cj).ravel()  # the coarse points' lattice indices
    best = coarse[np.argmin(costs_at(obs, w, P[coarse]), axis=1)]  # (T,)
    bi, bj = best // n_fine, best % n_fine
    off = np.arange(-ratio, ratio + 1)
    oi, oj = np.meshgrid(off, off, indexing="ij")
    fi = bi[:, None] + oi.ravel()[None]
    fj = bj[:, None] + oj.ravel()[None]
    inside = (fi >= 0) & (fi < n_fine) & (fj >= 0) & (fj < n_fine)
    idx = np.clip(fi, 0, n_fine - 1) * n_fine + np.clip(fj, 0, n_fine - 1)  # (T, window points)
    costs = costs_at(obs, w, P[idx])
    costs[~inside] = np.inf
    return grid[idx[np.arange(len(idx)), np.argmin(costs, axis=1)]]


def mmse(obs, w, lat, sigma):
    grid, P = lat
    est = np.empty((len(obs), 2))
    for s in range(0, len(obs), 2000):  # chunks keep the (T, 2601, A) array small
        c = costs_at(obs[s:s + 2000], w, P)
        wt = np.exp(-(c - c.min(axis=1, keepdims=True)) / (2.0 * sigma ** 2))
        est[s:s + 2000] = (wt @ grid) / wt.sum(axis=1, keepdims=True)
    return est


def distances(obs):
    return 10.0 ** ((P0 - obs) / (10.0 * ALPHA))


def trilat(anchors, d):
    """anchors (3, 2), d (T, 3) → (T, 2)."""
    a0, a1, a2 = anchors
    A = 2.0 * np.array([a1 - a0, a2 - a0])
    k = (anchors ** 2).sum(axis=1)
    b = np.stack([d[:, 0] ** 2 - d[:, 1] ** 2 + k[1] - k[0],
                  d[:, 0] ** 2 - d[:, 2] ** 2 + k[2] - k[0]], axis=1)
    return np.linalg.solve(A, b.T).T


def quadlat(anchors, d):
    triples = [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)]
    return np.mean([trilat(anchors[list(t)], d[:, list(t)]) for t in triples], axis=0)


def mds(anchors, d):
    n = len(anchors)
    T = len(d)
    D = np.zeros((T, n + 1, n + 1))
    aa = np.linalg.norm(anchors[:, None] - anchors[None], axis=-1)
    D[:, :n, :n] = aa
    D[:, :n, n] = d
    D[:, n, :n] = d
    J = np.eye(n + 1) - 1.0 / (n + 1)
    B = -0.5 * J @ (D ** 2) @ J
    lam, vec = np.linalg.eigh(B)  # ascending
    rel = vec[:, :, -2:] * np.sqrt(np.maximum(lam[:, None, -2:], 0.0))  # (T, n+1, 2)
    X, Y = rel[:, :n], anchors[None]
    mx, my = X.mean(axis=1, keepdims=True), Y.mean(axis=1, keepdims=True)
    Xc, Yc = X - mx, Y - my
    M = np.einsum("tai,taj->tij", Xc, Yc)  # cross-covariance Xcᵀ Yc
    U, S, Vt = np.linalg.svd(M)
    R = U @ Vt  # rotation or reflection
    scale = S.sum(axis=1) / (Xc ** 2).sum(axis=(1, 2))
    agent = rel[:, n][:, None, :] - mx
    return (scale[:, None, None] * (agent @ R))[:, 0] + my[:, 0]


def metrics(est, truth, runs):
    """est (P·runs, 2), truth (P, 2) → (mean per-point RMSE, bias x, bias y)."""
    err = est.reshape(len(truth), runs, 2) - truth[:, None, :]
    rmse = np.sqrt((err ** 2).sum(axis=-1).mean(axis=1))
    mean_err = err.mean(axis=1)
    return float(rmse.mean()), float(mean_err[:, 0].std()), float(mean_err[:, 1].std())


def study(runs, sigma, seed):
    rng = np.random.default_rng(seed)
    pts = points()
    truth_rep = np.repeat(pts, runs, axis=0)
    table = {}
    for n in (3, 4):
        anchors = ANCHORS4[:n]
        lat = lattice(anchors)
        d_true = np.linalg.norm(truth_rep[:, None] - anchors[None], axis=-1)
        z = rssi(d_true)[..., None] + sigma * rng.standard_normal((len(truth_rep), n, 2))
        for col in COLUMNS:
            obs, w = refine(z, col)
            table[(f"MLE-{n}", col)] = metrics(mle(obs, w, lat), pts, runs)
            # The cost already carries the weight (Ext-MCH: C·(mean − p)² = Σ_c (z_c − p)²).
            table[(f"MMSE-{n}", col)] = metrics(mmse(obs, w, lat, sigma), pts, runs)
            if col == "Ext-MCH":
                continue
            dist = distances(obs)
            table[(f"MDS-{n}", col)] = metrics(mds(anchors, dist), pts, runs)
            if n == 3:
                table[("TRLT-3", col)] = metrics(trilat(anchors, dist), pts, runs)
            else:
                table[("QUAD-4", col)] = metrics(quadlat(anchors, dist), pts, runs)
    return table


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--sigma", type=float, nargs="+", default=[2.0, 4.0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--coarse-divs", type=int, default=10, help="coarse grid divisions per side")
    ap.add_argument("--fine-divs", type=int, default=50, help="fine lattice divisions per side")
    ap.add_argument("--json", help="write the tables and the time here")
    args = ap.parse_args()
    if args.coarse_divs < 1 or args.fine_divs % args.coarse_divs != 0:
        ap.error("--fine-divs must be a multiple of --coarse-divs")
    global FINE_DIVS, COARSE_DIVS
    FINE_DIVS, COARSE_DIVS = args.fine_divs, args.coarse_divs
    t0 = time.perf_counter()
    out = {}
    for s in args.sigma:
        out[s] = study(args.runs, s, args.seed)
    secs = time.perf_counter() - t0
    for s, table in out.items():
        print(f"sigma = {s} dB, {args.runs} runs/point: mean per-point RMSE (m)")
        rows = sorted({r for r, _ in table}, key=lambda r: (r[-1], r))
        print(f"{'':8}" + "".join(f"{c:>12}" for c in COLUMNS))
        for r in rows:
            print(f"{r:8}" + "".join(f"{table[(r, c)][0]:12.3f}" if (r, c) in table else f"{'':>12}" for c in COLUMNS))
    print(f"numpy study: {secs:.3f} s")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"seconds": secs, "runs": args.runs, "tables": {
                str(s): [{"row": r, "column": c, "rmse": v[0], "bias_x": v[1], "bias_y": v[2]}
                         for (r, c), v in t.items()] for s, t in out.items()}}, f, indent=1)


if __name__ == "__main__":
    main()
