#!/usr/bin/env python3
"""Accuracy of the FK sine/cosine kernel (`sin_cos_kernel` in src/fk.rs) against mpmath.

The kernel is replicated operation by operation in Python floats (IEEE doubles, correctly rounded,
no fused multiply-add, like the Rust code), and compared with 60-digit sin and cos. Prints the
largest error in ulps of the correctly rounded result (relative accuracy) and the largest
absolute error. Needs `pip install mpmath`.

    python3 crates/kinematics/benches/sin_cos_ulp.py random 300000 2 7      # N, seed, |x| range
    python3 crates/kinematics/benches/sin_cos_ulp.py hard 63662             # doubles nearest n·π/2
"""
import math
import random
import struct
import sys

import mpmath

mpmath.mp.dps = 60


def bits(x):
    return struct.unpack("<Q", struct.pack("<d", x))[0]


def from_bits(b):
    return struct.unpack("<d", struct.pack("<Q", b & 0xFFFFFFFFFFFFFFFF))[0]


FRAC_2_PI = 6.36619772367581382433e-01
PIO2_1 = 1.57079632673412561417e00
PIO2_2 = 6.07710050630396597660e-11
PIO2_2T = 2.02226624879595063154e-21
ROUND = 6755399441055744.0
S1, S2, S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
S4, S5, S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
C1, C2, C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
C4, C5, C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


def kernel(x):
    """src/fk.rs sin_cos_kernel, same operations in the same order."""
    big = x * FRAC_2_PI + ROUND
    quadrant = bits(big)
    n = big - ROUND
    t = x - n * PIO2_1
    w = n * PIO2_2
    r = t - w
    w = n * PIO2_2T - ((t - r) - w)
    y0 = r - w
    y1 = (r - y0) - w
    z = y0 * y0
    z2 = z * z
    sr = S2 + z * (S3 + z * S4) + z * z2 * (S5 + z * S6)
    v = z * y0
    sin_r = y0 - ((z * (0.5 * y1 - v * sr) - y1) - v * S1)
    cr = z * (C1 + z * (C2 + z * C3)) + z2 * z2 * (C4 + z * (C5 + z * C6))
    hz = 0.5 * z
    w = 1.0 - hz
    cos_r = w + (((1.0 - w) - hz) + (z * cr - y0 * y1))
    swap = (-(quadrant & 1)) & 0xFFFFFFFFFFFFFFFF
    sb, cb = bits(sin_r), bits(cos_r)
    a = (sb & ~swap) | (cb & swap)
    b = (cb & ~swap) | (sb & swap)
    return from_bits(a ^ ((quadrant & 2) << 62)), from_bits(b ^ (((quadrant + 1) & 2) << 62))


def worst(xs):
    ulps, at, absolute = 0.0, None, 0.0
    for x in xs:
        s, c = kernel(x)
        mx = mpmath.mpf(x)
        for v, ref in ((s, mpmath.sin(mx)), (c, mpmath.cos(mx))):
            e = abs(mpmath.mpf(v) - ref)
            u = float(e / math.ulp(abs(float(ref))))
            if u > ulps:
                ulps, at = u, x
            absolute = max(absolute, float(e))
    return ulps, at, absolute


def main():
    mode = sys.argv[1]
    if mode == "random":
        n, seed, lim = int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
        rng = random.Random(seed)
        xs = [rng.uniform(-lim, lim) for _ in range(n)]
    else:
        nmax = int(sys.argv[2])
        xs = []
        for k in range(-nmax, nmax + 1):
            if k == 0:
                continue
            x0 = float(mpmath.mpf(k) * mpmath.pi / 2)
            for step in range(-4, 5):
                x = x0
                for _ in range(abs(step)):
                    x = math.nextafter(x, math.inf if step > 0 else -math.inf)
                xs.append(x)
    ulps, at, absolute = worst(xs)
    print(f"{mode} {sys.argv[2:]}: {len(xs)} points, worst {ulps:.3f} ulp (at x = {at!r}), "
          f"worst absolute error {absolute:.3g}")


if __name__ == "__main__":
    main()
