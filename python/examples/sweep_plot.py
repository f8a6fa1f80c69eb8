"""Two small seeded sweeps (sim-cell sweep): the median translation error of b1_from_b2 against the
number of handclasp points, per method, on the floor-wall cell at 1 mm alignment noise.

1. Geometry mode (points and noise only, fast): 100 trials per point count.
2. Robot mode (full simulated sessions: IK, reach limits, encoder quantisation, repeatability,
   and each trial's robots drawn within the cell's kinematic tolerances), where the whole-cell
   fits (`placement`, `kinematic`) run beside the points fit: 5 trials per point count.

Plots both with matplotlib when installed (sweep.png), and prints the tables either way.

    python python/examples/sweep_plot.py
"""

import handclasp as hc


def table(result):
    """(method, points, median, p95) rows of a sweep's summary (a DataFrame or a dict of columns)."""
    columns = result if isinstance(result, dict) else {k: list(result[k]) for k in result.columns}
    return list(zip(columns["method"], columns["n"], columns["e_tran_mm_median"], columns["e_tran_mm_p95"]))


geometry = table(hc.sweep(mounts=["floor-wall"], noise_mm=[1.0], spread_mm=[1000.0],
                          n_points=[4, 6, 8, 12], methods=["generic", "lsq", "constrained"], trials=100, seed=1))
robot = table(hc.sweep(mode="robot", mounts=["floor-wall"], noise_mm=[1.0], spread_mm=[1000.0],
                       n_points=[6, 12], methods=["lsq", "placement", "kinematic"], trials=5, seed=1,
                       kinematic_errors="tolerance"))
for title, rows in [("geometry mode, 100 trials", geometry), ("robot mode, 5 trials", robot)]:
    print(f"{title}\n{'method':<12} {'points':>6} {'median e_tran (mm)':>19} {'p95 (mm)':>9}")
    for method, n, median, p95 in rows:
        print(f"{method:<12} {int(n):>6} {median:>19.3f} {p95:>9.3f}")

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("matplotlib is not installed: no plot (pip install matplotlib)")
else:
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5), sharey=True)
    for ax, title, rows in [(axes[0], "geometry mode, 100 trials", geometry), (axes[1], "robot mode, 5 trials", robot)]:
        for method in sorted({r[0] for r in rows}):
            pts = sorted((int(n), m) for meth, n, m, _ in rows if meth == method)
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=method)
        ax.set_xlabel("handclasp points")
        ax.set_title(f"floor-wall, 1 mm noise, {title}", fontsize=9)
        ax.legend()
    axes[0].set_ylabel("median translation error of b1_from_b2 (mm)")
    fig.tight_layout()
    fig.savefig("sweep.png", dpi=120)
    print("wrote sweep.png")
