#!/usr/bin/env python3
"""Independent check of the face-to-face contact model of the CTU self-contacts (issue 12).

The self-contacts are flush contacts of two marker dodecahedra (studies/ctu-motoman/docs/findings.md,
"contact geometry"). Two contact models of the same rows, fitted from self-contact data only:
  distance  |c_L - c_R| = d                      (the sphere-like model the study used so far)
  face      n.(c_L - c_R) = d, n = unit(n_R - n_L) (distance along the touching faces' normal)
c_R, c_L are the marker centres (tool0 + [x, y, 0.354] m, x and y fitted with a 2 mm prior), n_R, n_L
the touching ring faces' outward normals (assigned once, at nominal kinematics, as the ring face
nearest the contact direction). Both arms' joint offsets S..T are fitted with a prior sigma chosen
by leave-one-pattern-out CV on the self-contact files (upper -> lower and back), as in study.py
section d. The chosen models are then scored on every tracker file with the study's protocol
(registration + reflector on one half, scored on the other, both ways). No tracker value is used in
any choice.

Python 3 + numpy + scipy; reuses study.py's FK and scoring, nothing of the Rust crates.
Run:  python3 tools/ctu-motoman/face_contact.py --data /work/shared/data/ctu-motoman
"""
import argparse
import math
import os
import sys

import numpy as np
from scipy.optimize import least_squares

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from dh import EE_MARKER, ee_tip  # noqa: E402
from study import ARMS, fk_frames, load_all, nominal_dh, section_a  # noqa: E402

RING_POLAR = math.atan(2.0)  # ring face normal from the top face normal (tool z) of a dodecahedron
SIGMA_CONTACT = 1e-3  # residual weight, m (only its ratio to the priors matters)
SIGMA_MARKER = 2e-3  # prior of the marker centres' x, y, m (a mounting tolerance, fixed beforehand)
SIGMA_GRID = [1e-4, 3e-4, 1e-3, 3e-3, 1e-2]  # prior of the joint offsets, rad


def frames(dhp, q):
    t = fk_frames(dhp, q)[-1]
    return t[:, :3, :3], t[:, :3, 3]


def ring_normals(phi0):
    k = np.arange(5)
    phi = phi0 + k * 2 * math.pi / 5
    return np.stack([math.sin(RING_POLAR) * np.cos(phi), math.sin(RING_POLAR) * np.sin(phi),
                     np.full(5, math.cos(RING_POLAR))], 1)


def assign_faces(sets):
    """phi0 of the rings (both markers) and, per set, the touching face index of each arm."""
    tip = ee_tip(EE_MARKER)
    dirs = {arm: [] for arm in ARMS}
    for s in sets:
        (rr, tr), (rl, tl) = (frames(nominal_dh(a), s["q"][a]) for a in ARMS)
        cr, cl = np.einsum("nij,j->ni", rr, tip) + tr, np.einsum("nij,j->ni", rl, tip) + tl
        u = cl - cr
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        dirs["right"].append(np.einsum("nji,nj->ni", rr, u))
        dirs["left"].append(np.einsum("nji,nj->ni", rl, -u))
    allv = np.concatenate([np.concatenate(dirs[a]) for a in ARMS])
    az = np.arctan2(allv[:, 1], allv[:, 0])
    phi0 = (math.atan2(np.sin(5 * az).mean(), np.cos(5 * az).mean()) / 5) % (2 * math.pi / 5)
    normals = ring_normals(phi0)
    faces = [{a: np.argmax(dirs[a][i] @ normals.T, axis=1) for a in ARMS} for i in range(len(sets))]
    return phi0, normals, faces


class Model:
    """x = [offsets right (6), offsets left (6), marker xy right (2), marker xy left (2), d]."""

    n = 17

    def __init__(self, kind, normals):
        self.kind = kind
        self.normals = normals

    def robots(self, x):
        out = {}
        for k, arm in enumerate(ARMS):
            dhp = nominal_dh(arm).copy()
            dhp[1:7, 3] += x[6 * k:6 * k + 6]
            out[arm] = dhp
        return out

    def residual(self, x, sets, faces):
        rob = self.robots(x)
        tips = {arm: ee_tip(EE_MARKER) + np.array([x[12 + 2 * k], x[13 + 2 * k], 0.0])
                for k, arm in enumerate(ARMS)}
        out = []
        for s, f in zip(sets, faces):
            (rr, tr), (rl, tl) = (frames(rob[a], s["q"][a]) for a in ARMS)
            cr = np.einsum("nij,j->ni", rr, tips["right"]) + tr
            cl = np.einsum("nij,j->ni", rl, tips["left"]) + tl
            if self.kind == "distance":
                out.append(np.linalg.norm(cl - cr, axis=1) - x[16])
            else:
                nr = np.einsum("nij,nj->ni", rr, self.normals[f["right"]])
                nl = np.einsum("nij,nj->ni", rl, self.normals[f["left"]])
                nbar = nr - nl
                nbar /= np.linalg.norm(nbar, axis=1, keepdims=True)
                out.append(np.einsum("ni,ni->n", nbar, cl - cr) - x[16])
        return np.concatenate(out)

    def fit(self, sets, faces, sigma):
        x0 = np.zeros(self.n)
        x0[16] = 0.116

        def res(x):
            prior = np.concatenate([x[:12] / sigma, x[12:16] / SIGMA_MARKER])
            return np.concatenate([self.residual(x, sets, faces) / SIGMA_CONTACT, prior])

        return least_squares(res, x0, method="trf", xtol=1e-12, ftol=1e-12, max_nfev=200).x


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="/work/shared/data/ctu-motoman")
    args = ap.parse_args()
    data = load_all(args.data)
    names = sorted(n for n in data if n.startswith("no_leica_self"))
    sets = [data[n] for n in names]
    phi0, normals, faces = assign_faces(sets)
    print(f"ring azimuth phi0 = {math.degrees(phi0):.2f} deg; {sum(len(s['e']) for s in sets)} self-contact rows")
    patterns = [[i for i, n in enumerate(names) if "upper" in n], [i for i, n in enumerate(names) if "lower" in n]]
    nominal = {r["file"] + "/" + r["arm"]: r for r in section_a(data)}
    print("\nleave-one-pattern-out CV (contact residual rms, mm):")
    chosen = {}
    for kind in ("distance", "face"):
        m = Model(kind, normals)
        cv = {}
        for s in SIGMA_GRID:
            errs = []
            for k in range(2):
                tr, te = patterns[k], patterns[1 - k]
                x = m.fit([sets[i] for i in tr], [faces[i] for i in tr], s)
                errs.append(m.residual(x, [sets[i] for i in te], [faces[i] for i in te]))
            e = np.concatenate(errs)
            c = math.sqrt(np.mean(e ** 2))
            se = np.std(e ** 2, ddof=1) / (2 * c * math.sqrt(len(e)))
            cv[s] = (c, se)
            print(f"  {kind:8s} sigma {s * 1e3:6.2f} mrad: {c * 1e3:.4f} (SE {se * 1e3:.4f})")
        best = min(cv, key=lambda s: cv[s][0])
        thr = cv[best][0] + cv[best][1]
        pick = min(s for s in SIGMA_GRID if cv[s][0] <= thr)  # one-SE rule: the smaller prior
        chosen[kind] = pick
        print(f"  {kind}: one-SE rule picks sigma {pick * 1e3:g} mrad")
    print("\nheld-out tracker rms, mm (registration + reflector on one half, scored on the other):")
    rows = {}
    for kind, s in chosen.items():
        m = Model(kind, normals)
        x = m.fit(sets, faces, s)
        resid = m.residual(x, sets, faces)
        print(f"  {kind}: contact residual rms {math.sqrt(np.mean(resid ** 2)) * 1e3:.3f} mm; "
              f"offsets R [{', '.join(f'{v * 1e3:+.2f}' for v in x[:6])}] mrad, "
              f"L [{', '.join(f'{v * 1e3:+.2f}' for v in x[6:12])}] mrad; marker R "
              f"({x[12] * 1e3:+.2f}, {x[13] * 1e3:+.2f}) L ({x[14] * 1e3:+.2f}, {x[15] * 1e3:+.2f}) mm; "
              f"d {x[16] * 1e3:.2f} mm")
        for r in section_a(data, m.robots(x), kind):
            rows.setdefault(r["file"] + "/" + r["arm"], {})[kind] = r["rms"]
    print(f"\n  {'file/arm':45s} {'nominal':>8s} {'distance':>9s} {'face':>8s}")
    wins = {k: 0 for k in chosen}
    for key in sorted(rows):
        nom = nominal[key]["rms"]
        for k in chosen:
            wins[k] += rows[key][k] < nom
        print(f"  {key:45s} {nom:8.3f} {rows[key]['distance']:9.3f} {rows[key]['face']:8.3f}")
    print(f"  beats nominal on: " + ", ".join(f"{k} {wins[k]}/{len(rows)}" for k in chosen))


if __name__ == "__main__":
    main()
