#!/usr/bin/env python3
"""Batch-vectorised numpy baseline of sim-cell's geometry-mode sweep (issue 4's reference).

The same study as `sim-cell sweep --points 4 --methods generic --layout tetrahedron`, for one grid
cell: the paper's placement of the chosen cell (Table 1), a regular tetrahedron of edge `spread`
(P1-P3 a horizontal equilateral triangle with a uniform random yaw, P4 above its centroid) centred
on the cell's teach centre, the operator's alignment error eps ~ N(0, sigma^2 I) added to robot 1's
point in b1 axes, `p_b2 = b2_from_b1 (p_b1 + eps)`; the generic 4-point fit `H = A B^-1` (batched
`np.linalg.solve`), the nearest rotation of H's 3x3 block by SVD with the determinant guard, eq (12)
for the translation; then e_tran (eq 34), the geodesic angle and e_rot (eq 33 as calib-core reads
it: at a true theta within 1 deg of 0 or 180 deg, max(tilt of the z axis, |yaw error|); elsewhere
the nearest of the two exact ZYZ branches, differences wrapped).

Everything is vectorised over trials: (N, 4, 3) point stacks, (N, 4, 4) solves, (N, 3, 3) SVDs.
Random numbers come from numpy's PCG64, so results agree with sim-cell's statistically, not
trial by trial.

Timed: drawing, fitting and the metrics of all trials (the summary statistics after are not).

    python3 sweep_numpy.py --trials 1000000 --batch 100000 --repeat 3
    OMP_NUM_THREADS=1 python3 sweep_numpy.py --trials 1000000 --procs 2   # both cores
    python3 sweep_numpy.py --mounts floor-wall --noise-mm 1 --spread-mm 1000 --trials 200000
"""

import argparse
import json
import os
import time

import numpy as np

# Table 1 placements (mm, ZYZ deg) and teach centres (mm), as in sim_cell::placement.
CELLS = {
    "floor-floor": ([37.9, 1476.5, 54.5], [-0.001, 0.001, -44.5], [150.0, 690.0, 500.0]),
    "floor-wall": ([1303.3, -102.3, 1386.3], [180.0, 89.874, -179.997], [475.0, -50.0, 995.0]),
    "floor-ceiling": ([1500.1, 500.0, 1499.9], [0.0, 180.001, 0.001], [750.0, 250.0, 720.0]),
}
# calib_core::ZYZ_SINGULAR_BAND_RAD
SINGULAR_BAND_RAD = np.pi / 180.0


def rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_from_zyz(zyz):
    """eq 31: Rz(phi) Ry(theta) Rz(psi), rad."""
    return rz(zyz[0]) @ ry(zyz[1]) @ rz(zyz[2])


def wrap(a):
    """Wrap to (-pi, pi]."""
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def zyz_from_rotation(r):
    """eq 32 on a (N, 3, 3) stack: theta in [0, pi], phi = 0 where a_x = a_y = 0."""
    ax, ay, az = r[:, 0, 2], r[:, 1, 2], r[:, 2, 2]
    phi = np.where((ax == 0.0) & (ay == 0.0), 0.0, np.arctan2(ay, ax))
    c, s = np.cos(phi), np.sin(phi)
    theta = np.arctan2(c * ax + s * ay, az)
    psi = np.arctan2(-s * r[:, 0, 0] + c * r[:, 1, 0], -s * r[:, 0, 1] + c * r[:, 1, 1])
    return wrap(phi), theta, wrap(psi)


def e_rot(zyz_true, r_true, r_est):
    """eq 33 as calib_core::e_rot_zyz reads it, rad, for a (N, 3, 3) stack of estimates."""
    phi_t, theta_t, psi_t = zyz_true
    if abs(np.sin(theta_t)) < np.sin(SINGULAR_BAND_RAD):
        a_t = r_true[:, 2]
        a_e = r_est[:, :, 2]
        tilt = np.arctan2(np.linalg.norm(np.cross(a_t, a_e), axis=1), a_e @ a_t)
        if np.cos(theta_t) > 0.0:
            yaw_t = phi_t + psi_t
            yaw_e = np.arctan2(r_est[:, 1, 0] - r_est[:, 0, 1], r_est[:, 0, 0] + r_est[:, 1, 1])
        else:
            yaw_t = phi_t - psi_t
            yaw_e = np.arctan2(-r_est[:, 1, 0] - r_est[:, 0, 1], r_est[:, 1, 1] - r_est[:, 0, 0])
        return np.maximum(tilt, np.abs(wrap(yaw_e - yaw_t)))
    phi, theta, psi = zyz_from_rotation(r_est)

    def worst(p, t, s):
        return np.maximum.reduce(
            [np.abs(wrap(p - phi_t)), np.abs(wrap(t - theta_t)), np.abs(wrap(s - psi_t))]
        )

    # (Estimates with |sin theta| < 1e-9 would need calib-core's anchored readings; a regular
    # truth is more than 1 deg from them, so none occurs at these noise levels.)
    return np.minimum(worst(phi, theta, psi), worst(wrap(phi + np.pi), -theta, wrap(psi + np.pi)))


def run_batch(rng, n, cell, sigma_m, spread_m):
    """n trials: returns (e_tran m, geodesic rad, e_rot rad) arrays."""
    xyz_mm, zyz_deg, centre_mm = CELLS[cell]
    zyz_true = np.radians(zyz_deg)
    r_true = rotation_from_zyz(zyz_true)
    t_true = np.array(xyz_mm) / 1000.0
    centre = np.array(centre_mm) / 1000.0

    # Regular tetrahedron of edge `spread`, random yaw (sim_cell::layout, Layout::Tetrahedron).
    yaw = rng.random(n) * 2.0 * np.pi
    r_circ = spread_m / np.sqrt(3.0)
    h = spread_m * np.sqrt(2.0 / 3.0)
    ang = yaw[:, None] + np.array([0.0, 2.0 * np.pi / 3.0, 4.0 * np.pi / 3.0])[None, :]
    p1 = np.empty((n, 4, 3))
    p1[:, :3, 0] = r_circ * np.cos(ang)
    p1[:, :3, 1] = r_circ * np.sin(ang)
    p1[:, :3, 2] = -h / 4.0
    p1[:, 3] = [0.0, 0.0, 0.75 * h]
    p1 += centre
    # Alignment error in b1 axes, then robot 2's reading: p_b2 = R^T (p_b1 + eps - T).
    eps = rng.standard_normal((n, 4, 3)) * sigma_m
    p2 = (p1 + eps - t_true) @ r_true  # row vectors: (R^T x)^T = x^T R

    # Generic 4-point fit: A = H B, H = A B^-1  <=>  B^T H^T = A^T.
    a = np.ones((n, 4, 4))
    b = np.ones((n, 4, 4))
    a[:, :3, :] = p1.transpose(0, 2, 1)
    b[:, :3, :] = p2.transpose(0, 2, 1)
    h_t = np.linalg.solve(b.transpose(0, 2, 1), a.transpose(0, 2, 1))
    m = h_t.transpose(0, 2, 1)[:, :3, :3]
    # Nearest rotation (polar factor) by SVD, determinant guarded.
    u, _, vt = np.linalg.svd(m)
    d = np.sign(np.linalg.det(u @ vt))
    u[:, :, 2] *= d[:, None]
    r_est = u @ vt
    # eq 12: T = mean_i (p1_i - R p2_i).
    t_est = (p1 - p2 @ r_est.transpose(0, 2, 1)).mean(axis=1)

    e_tran = np.abs(t_est - t_true).max(axis=1)
    # Geodesic angle of R_true^T R_est: atan2(|vee(Q - Q^T)| / 2, (tr Q - 1) / 2), exact at any angle.
    q = r_true.T @ r_est
    vee = np.stack([q[:, 2, 1] - q[:, 1, 2], q[:, 0, 2] - q[:, 2, 0], q[:, 1, 0] - q[:, 0, 1]], 1)
    geodesic = np.arctan2(
        0.5 * np.linalg.norm(vee, axis=1), 0.5 * (np.trace(q, axis1=1, axis2=2) - 1.0)
    )
    return e_tran, geodesic, e_rot(zyz_true, r_true, r_est)


def timed_run(args, seed, trials, barrier=None):
    """Runs `trials` trials in batches; returns (wall s, cpu s, [(e_tran, geodesic, e_rot)])."""
    rng = np.random.default_rng(seed)
    if barrier is not None:
        barrier.wait()
    out = []
    t0 = time.perf_counter()
    cpu0 = time.process_time()
    done = 0
    while done < trials:
        n = min(args.batch, trials - done)
        out.append(run_batch(rng, n, args.mounts, args.noise_mm / 1000.0, args.spread_mm / 1000.0))
        done += n
    return time.perf_counter() - t0, time.process_time() - cpu0, out


def _worker(job):
    args, seed, trials, barrier = job
    return timed_run(args, seed, trials, barrier)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mounts", default="floor-floor", choices=sorted(CELLS))
    ap.add_argument("--noise-mm", type=float, default=1.0)
    ap.add_argument("--spread-mm", type=float, default=1000.0)
    ap.add_argument("--trials", type=int, default=1_000_000)
    ap.add_argument("--batch", type=int, default=100_000, help="trials per vectorised batch")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs; the best is reported")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--procs", type=int, default=1, help="worker processes (e.g. 2 for 2 cores)")
    ap.add_argument("--json", action="store_true", help="print one JSON line")
    args = ap.parse_args()

    best = None
    for rep in range(args.repeat):
        if args.procs == 1:
            wall, cpu, out = timed_run(args, [args.seed, rep], args.trials)
        else:
            # One share of the trials per process, started together after a barrier; the
            # throughput is all trials over the slowest process's time.
            import multiprocessing as mp

            ctx = mp.get_context("fork")
            barrier = ctx.Manager().Barrier(args.procs)
            share = -(-args.trials // args.procs)
            jobs = [(args, [args.seed, rep, k], share, barrier) for k in range(args.procs)]
            with ctx.Pool(args.procs) as pool:
                parts = pool.map(_worker, jobs)
            wall = max(p[0] for p in parts)
            cpu = sum(p[1] for p in parts)
            out = [o for p in parts for o in p[2]]
        if best is None or wall < best[0]:
            best = (wall, cpu, out)
    wall, cpu, out = best
    trials = sum(len(o[0]) for o in out)
    e_tran = np.concatenate([o[0] for o in out]) * 1000.0
    geodesic = np.degrees(np.concatenate([o[1] for o in out]))
    erot = np.degrees(np.concatenate([o[2] for o in out]))
    res = {
        "mounts": args.mounts,
        "noise_mm": args.noise_mm,
        "spread_mm": args.spread_mm,
        "trials": trials,
        "batch": args.batch,
        "procs": args.procs,
        "wall_s": round(wall, 4),
        "cpu_s": round(cpu, 4),
        "trials_per_s": round(trials / wall),
        "trials_per_cpu_s": round(trials / cpu),
        "numpy": np.__version__,
        "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
        "e_tran_mm_median": float(np.median(e_tran)),
        "e_tran_mm_p95": float(np.quantile(e_tran, 0.95)),
        "geodesic_deg_median": float(np.median(geodesic)),
        "geodesic_deg_p95": float(np.quantile(geodesic, 0.95)),
        "e_rot_deg_median": float(np.median(erot)),
        "e_rot_deg_p95": float(np.quantile(erot, 0.95)),
    }
    if args.json:
        print(json.dumps(res))
    else:
        for k, v in res.items():
            print(f"{k}: {v}")


if __name__ == "__main__":
    main()
