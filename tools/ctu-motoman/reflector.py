#!/usr/bin/env python3
"""How well do the tracker files pin the Leica reflector's offset on the flange? (issue 12)

For every tracker file and moving arm: the reflector offset fitted freely together with one rigid
registration (all poses, nominal DH), against the registration alone with the reflector held at the
repository's nominal EE row. With --cv: the right arm's joint offsets (prior sigma 1 mrad) fitted
from all right-arm tracker files, with the reflector free per file, free but shared, or held by a
prior of 10 / 3 / 1 mm around the nominal; each file scored by protocol a of study.py after
leaving it (and its twin run) out.

Run:  python3 tools/ctu-motoman/reflector.py --data /work/shared/data/ctu-motoman [--cv]
(about 1 s; --cv about 10 min on the shared 2-core machine). Units in code m/rad, printed mm/mrad.
"""
import argparse
import os
import sys

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import study as S  # noqa: E402


def tracker_files(data):
    return [n for n in sorted(data) if n.startswith("leica") and "rep" not in n]


def free_vs_nominal(data):
    print("file | arm | free reflector (mm) | rms free | rms nominal reflector (mm)")
    for name in tracker_files(data):
        d = data[name]
        idx = S.tracker_rows(d)
        for arm in S.moving_arms(d):
            q, p = d["q"][arm][idx], d["p"][idx]
            dh = S.nominal_dh(arm)

            def fk(qq, tip, dh=dh):
                return S.fk_point(dh, qq, tip)

            x = S.fit_reg_tip_fn(fk, q, p, arm)
            free = np.linalg.norm(Rotation.from_rotvec(x[:3]).apply(fk(q, x[6:9])) + x[3:6] - p, axis=1)
            tip0 = S.ee_tip(S.EE_REFLECTOR[arm])
            b = fk(q, tip0)
            r, t = S.kabsch(b, p)
            held = np.linalg.norm(b @ r.T + t - p, axis=1)
            rms = lambda e: np.sqrt(np.mean(e ** 2)) * 1e3  # noqa: E731
            print(f"{name} | {arm} | {np.round(x[6:9] * 1e3, 1)} | {rms(free):.3f} | {rms(held):.3f}")


def right_sets(data):
    out = {}
    for n in tracker_files(data):
        d = data[n]
        if "right" in S.moving_arms(data[n]) and "left_hand" not in n:
            idx = S.tracker_rows(d)
            out[n] = (d["q"]["right"][idx], d["p"][idx])
    return out


def fit_offsets(sets, names, sig_off, sig_tip, shared):
    tip0 = S.ee_tip(S.EE_REFLECTOR["right"])
    nf, nt = len(names), (1 if shared else len(names))
    x0 = np.zeros(6 + 3 * nt + 6 * nf)
    x0[6:6 + 3 * nt] = np.tile(tip0, nt)
    for i, n in enumerate(names):
        q, p = sets[n]
        r, t = S.kabsch(S.fk_point(S.nominal_dh("right"), q, tip0), p)
        k = 6 + 3 * nt + 6 * i
        x0[k:k + 3], x0[k + 3:k + 6] = Rotation.from_matrix(r).as_rotvec(), t

    def dh_of(off):
        dh = S.nominal_dh("right").copy()
        dh[1:, 3] += off
        return dh

    def res(x):
        dh, out = dh_of(x[:6]), []
        for i, n in enumerate(names):
            q, p = sets[n]
            tip = x[6 + 3 * (0 if shared else i):9 + 3 * (0 if shared else i)]
            k = 6 + 3 * nt + 6 * i
            pred = Rotation.from_rotvec(x[k:k + 3]).apply(S.fk_point(dh, q, tip)) + x[k + 3:k + 6]
            out.append(((pred - p) / 2e-4).ravel())
        return np.concatenate(out + [x[:6] / sig_off, (x[6:6 + 3 * nt] - np.tile(tip0, nt)) / sig_tip])

    x = least_squares(res, x0, x_scale="jac", xtol=1e-12, ftol=1e-12, max_nfev=300).x
    return x, dh_of(x[:6])


def cv(data):
    sets = right_sets(data)
    files = list(sets)
    score = {}
    for n in files:
        q, p = sets[n]
        e = S.holdout_score_fixed(S.nominal_dh("right"), q, p, "right")
        score[n] = np.sqrt(np.mean(e ** 2)) * 1e3
    pooled = lambda s: np.sqrt(np.mean([s[n] ** 2 for n in files]))  # noqa: E731
    print(f"nominal: pooled over files {pooled(score):.3f} mm")
    for sig_tip in (10.0, 1e-2, 3e-3, 1e-3):
        for shared in (False, True):
            held = {}
            for n in files:
                train = [m for m in files if m[:-5] != n[:-5]]  # leave the file and its twin run out
                _, dh = fit_offsets(sets, train, 1e-3, sig_tip, shared)
                q, p = sets[n]
                e = S.holdout_score_fixed(dh, q, p, "right")
                held[n] = np.sqrt(np.mean(e ** 2)) * 1e3
            x, _ = fit_offsets(sets, files, 1e-3, sig_tip, shared)
            worse = [n for n in files if held[n] > score[n]]
            print(f"reflector prior {'free' if sig_tip > 1 else f'{sig_tip * 1e3:g} mm'}, "
                  f"{'shared' if shared else 'per file'}: left-out pooled {pooled(held):.3f} mm; "
                  f"worse than nominal: {worse}; offsets S..T mrad {np.round(x[:6] * 1e3, 2)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True)
    ap.add_argument("--cv", action="store_true")
    a = ap.parse_args()
    data = S.load_all(a.data)
    free_vs_nominal(data)
    if a.cv:
        cv(data)


if __name__ == "__main__":
    main()
