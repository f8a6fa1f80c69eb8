#!/usr/bin/env python3
"""Seeded rigid handclasp points for the calibrate row-count benchmark (BENCHMARKS.md).

Usage: python3 tools/bench/gen_points.py N OUT.csv [SEED]

p_b2 on a jittered cubic lattice in [-750, 750] x [-750, 750] x [0, 1500] mm (so no two rows fall
within calib-core's duplicate distance, whatever N), p_b1 = Rz(0.7 rad) p_b2 + (1200, -300, 50) mm
plus 0.3 mm Gaussian noise per coordinate. Header r1_x_mm,...,r2_z_mm (4 decimals).
"""
import math
import random
import sys


def main():
    n, out = int(sys.argv[1]), sys.argv[2]
    rng = random.Random(int(sys.argv[3]) if len(sys.argv) > 3 else 7)
    a = 0.7
    rot = [[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]]
    t = [1200.0, -300.0, 50.0]
    k = round(n ** (1 / 3)) + 1
    step = 1500.0 / k
    written = 0
    with open(out, "w") as f:
        f.write("r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm\n")
        for i in range(k):
            for j in range(k):
                for l in range(k):
                    if written == n:
                        return
                    jit = lambda: rng.uniform(-0.2, 0.2) * step
                    p2 = [-750 + i * step + jit(), -750 + j * step + jit(), l * step + jit()]
                    p1 = [sum(rot[r][c] * p2[c] for c in range(3)) + t[r] + rng.gauss(0, 0.3) for r in range(3)]
                    f.write(",".join(f"{v:.4f}" for v in p1 + p2) + "\n")
                    written += 1


if __name__ == "__main__":
    main()
