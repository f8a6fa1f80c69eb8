"""A small seeded sweep of the points fit (sim-cell sweep's geometry mode): the median
translation error of b1_from_b2 against the number of handclasp points, per method, on the
floor-wall cell at 1 mm alignment noise. Plots it with matplotlib when installed (sweep.png),
and prints the table either way.

    python python/examples/sweep_plot.py
"""

import handclasp as hc

table = hc.sweep(mounts=["floor-wall"], noise_mm=[1.0], spread_mm=[1000.0],
                 n_points=[4, 6, 8, 12], methods=["generic", "lsq", "constrained"], trials=100, seed=1)
columns = table if isinstance(table, dict) else {k: list(table[k]) for k in table.columns}
rows = list(zip(columns["method"], columns["n"], columns["e_tran_mm_median"], columns["e_tran_mm_p95"]))
print(f"{'method':<12} {'points':>6} {'median e_tran (mm)':>19} {'p95 (mm)':>9}")
for method, n, median, p95 in rows:
    print(f"{method:<12} {int(n):>6} {median:>19.3f} {p95:>9.3f}")

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("matplotlib is not installed: no plot (pip install matplotlib)")
else:
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for method in sorted(set(columns["method"])):
        pts = sorted((int(n), m) for meth, n, m, _ in rows if meth == method)
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=method)
    ax.set_xlabel("handclasp points")
    ax.set_ylabel("median translation error of b1_from_b2 (mm)")
    ax.set_title("floor-wall, 1 mm alignment noise, 100 trials")
    ax.legend()
    fig.tight_layout()
    fig.savefig("sweep.png", dpi=120)
    print("wrote sweep.png")
