#!/usr/bin/env python3
"""Independent handclasp-session generator (issue #5: "sessions it has never seen").

Shares no code with the Rust crates: it parses the URDFs in robots/ with xml.etree, has its own
forward kinematics, gravity torques and damped-least-squares IK, and applies hidden effects as
issue #5 defines them ("value is the true robot minus the nominal model"):

- joint_offset:  true joint angle = reported + value                          (deg)
- joint_scale:   true joint angle = reported * (1 + value)                    (ratio)
- link_length:   true joint origin = URDF <origin xyz> + value along axis,
                 axis of the parent link's frame                              (mm)
- tip_offset:    true tip = nominal tip + value along axis, tool0 frame       (mm)
- mount_tilt:    true base = nominal base turned by value about its x or y    (deg)
- compliance:    true joint angle = reported + value * tau, tau the torque gravity exerts about
                 the joint axis (positive in the joint's positive sense), computed here from the
                 URDF inertials at the true posture (deg per kN*m, as the crates' README states)

A session: teach points P (b1) in the cell's common workspace; the TRUE robots are solved so that
robot 1's true tip is at P and robot 2's at P + eps (isotropic alignment noise, sigma in b1), tool
axes head-on; the controllers report the joint angles (rounded to 0.001 deg) and the tips the
NOMINAL model computes from them. Files: cell TOML and session CSV in the formats of
docs/formats.md, plus truth JSON (the effects, the sigma and a noise-free signal figure).

Usage: gen_session.py --out DIR --seed S [--category noise|joint_offset|...|two_effects]
                      [--mounts floor-floor|floor-wall|floor-ceiling] [--n N] [--sigma-mm S]
"""

import argparse
import json
import math
import os
import sys
import xml.etree.ElementTree as ET

import numpy as np

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
G = 9.81
ENCODER_DEG = 0.001


# ----------------------------------------------------------------------------- maths

def rot_x(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rot_rpy(rpy):
    """URDF: R = Rz(yaw) * Ry(pitch) * Rx(roll)."""
    return rot_z(rpy[2]) @ rot_y(rpy[1]) @ rot_x(rpy[0])


def skew(k):
    return np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])


def rot_axis(axis, a):
    """Rodrigues: rotation by a about unit axis."""
    k = np.asarray(axis, float)
    kx = skew(k / np.linalg.norm(k))
    return np.eye(3) + math.sin(a) * kx + (1 - math.cos(a)) * (kx @ kx)


def cross_rows(a, b):
    """Row-wise cross product of (n,3) a with (n,3) or (3,) b (faster than np.cross here)."""
    b = np.broadcast_to(b, a.shape)
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                     a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def cross3(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def rot_zyz(phi, theta, psi):
    return rot_z(phi) @ rot_y(theta) @ rot_z(psi)


def zyz_from(r):
    """ZYZ angles (rad) of r, R = Rz(phi) Ry(theta) Rz(psi); phi = 0 at the singularity."""
    ax, ay, az = r[0, 2], r[1, 2], r[2, 2]
    if math.hypot(ax, ay) < 1e-12:
        phi = 0.0
    else:
        phi = math.atan2(ay, ax)
    theta = math.atan2(math.cos(phi) * ax + math.sin(phi) * ay, az)
    psi = math.atan2(-math.sin(phi) * r[0, 0] + math.cos(phi) * r[1, 0],
                     -math.sin(phi) * r[0, 1] + math.cos(phi) * r[1, 1])
    return phi, theta, psi


def kabsch(a, b):
    """R, t minimising sum |a_i - (R b_i + t)|^2."""
    ca, cb = a.mean(0), b.mean(0)
    h = (b - cb).T @ (a - ca)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1, 1, d]) @ u.T
    return r, ca - r @ cb


# ----------------------------------------------------------------------------- URDF

class Robot:
    """Serial chain from the URDF root to `tool_link`, parsed with xml.etree."""

    def __init__(self, path, tool_link="tool0"):
        self.path = path
        root = ET.parse(path).getroot()
        self.name = root.get("name")
        links = {}
        for link in root.findall("link"):
            inert = link.find("inertial")
            if inert is not None:
                o = inert.find("origin")
                com = np.array([float(v) for v in o.get("xyz", "0 0 0").split()]) if o is not None else np.zeros(3)
                links[link.get("name")] = (float(inert.find("mass").get("value")), com)
            else:
                links[link.get("name")] = (0.0, np.zeros(3))
        by_child = {}
        for j in root.findall("joint"):
            by_child[j.find("child").get("link")] = j
        chain = []
        cur = tool_link
        while cur in by_child:
            j = by_child[cur]
            chain.append(j)
            cur = j.find("parent").get("link")
        chain.reverse()
        self.root_link = cur
        # Each element: dict(type, xyz, rpy, axis, lower, upper, name, child_mass, child_com)
        self.elems = []
        for j in chain:
            o = j.find("origin")
            xyz = np.array([float(v) for v in o.get("xyz", "0 0 0").split()]) if o is not None else np.zeros(3)
            rpy = np.array([float(v) for v in o.get("rpy", "0 0 0").split()]) if o is not None else np.zeros(3)
            a = j.find("axis")
            axis = np.array([float(v) for v in a.get("xyz").split()]) if a is not None else np.array([1.0, 0, 0])
            lim = j.find("limit")
            typ = j.get("type")
            m, com = links[j.find("child").get("link")]
            self.elems.append(dict(
                name=j.get("name"), type=typ, xyz=xyz, rpy=rpy, axis=axis / np.linalg.norm(axis),
                lower=float(lim.get("lower")) if lim is not None else -math.pi,
                upper=float(lim.get("upper")) if lim is not None else math.pi,
                mass=m, com=com))
        self.actuated = [k for k, e in enumerate(self.elems) if e["type"] in ("revolute", "continuous")]
        self.dof = len(self.actuated)
        self.lower = np.array([self.elems[k]["lower"] for k in self.actuated])
        self.upper = np.array([self.elems[k]["upper"] for k in self.actuated])


def zero_errors(dof):
    return dict(offset=np.zeros(dof), scale=np.zeros(dof), dxyz=np.zeros((dof, 3)), tip=np.zeros(3),
                mount=np.eye(3), compliance=np.zeros(dof))


class Chain:
    """A robot with a set of true errors (zero errors: the nominal model) and a tip offset."""

    def __init__(self, robot, tip, errors=None):
        self.robot = robot
        self.err = errors if errors is not None else zero_errors(robot.dof)
        self.tip = np.asarray(tip, float) + self.err["tip"]
        # Fixed part of each element: origin transform (with the link-length error).
        self.origins = []
        j = 0
        for e in robot.elems:
            xyz = e["xyz"].copy()
            if e["type"] != "fixed":
                xyz = xyz + self.err["dxyz"][j]
                j += 1
            kx = skew(e["axis"])
            self.origins.append((rot_rpy(e["rpy"]), xyz, kx, kx @ kx))

    def pose(self, q_true):
        """Lean FK for IK: joint axes and origins (base), tip position, flange rotation."""
        r = self.err["mount"].copy()
        t = np.zeros(3)
        axes, origins = [], []
        j = 0
        for e, (ro, xo, kx, kx2) in zip(self.robot.elems, self.origins):
            t = t + r @ xo
            r = r @ ro
            if e["type"] != "fixed":
                axes.append(r @ e["axis"])
                origins.append(t)
                a = q_true[j]
                r = r @ (np.eye(3) + math.sin(a) * kx + (1 - math.cos(a)) * kx2)
                j += 1
        return np.array(axes), np.array(origins), t + r @ self.tip, r

    def frames(self, q_true):
        """Per actuated joint (axis in base, origin in base, carried mass moments), plus the tip
        position and the flange rotation, all in the NOMINAL base frame (mount applied)."""
        r = self.err["mount"].copy()
        t = np.zeros(3)
        axes, origins, coms, masses = [], [], [], []
        j = 0
        for e, (ro, xo, _, _) in zip(self.robot.elems, self.origins):
            t = t + r @ xo
            r = r @ ro
            if e["type"] != "fixed":
                axes.append(r @ e["axis"])
                origins.append(t.copy())
                r = r @ rot_axis(e["axis"], q_true[j])
                j += 1
            if e["mass"] > 0:
                coms.append(t + r @ e["com"])
                masses.append((e["mass"], j - 1))  # carried by the last actuated joint so far
        p = t + r @ self.tip
        return np.array(axes), np.array(origins), coms, masses, p, r

    def tip_pos(self, q_true):
        return self.pose(q_true)[2]

    def gravity_torques(self, q_true, g_base):
        """tau_i = z_i . sum_{links carried by i} (c_k - o_i) x (m_k g), N*m; g_base in the
        NOMINAL base frame (the mount is inside `frames`)."""
        axes, origins, coms, masses, _, _ = self.frames(q_true)
        tau = np.zeros(self.robot.dof)
        for i in range(self.robot.dof):
            s = 0.0
            for c, (m, owner) in zip(coms, masses):
                if owner >= i:
                    s += axes[i] @ cross3(c - origins[i], m * g_base)
            tau[i] = s
        return tau

    def q_true_from_rep(self, q_rep, g_base):
        """Applies offset, scale and compliance (tau at the true posture, by fixed point)."""
        q = q_rep * (1 + self.err["scale"]) + self.err["offset"]
        if np.any(self.err["compliance"] != 0):
            for _ in range(4):
                q = q_rep * (1 + self.err["scale"]) + self.err["offset"] + \
                    self.err["compliance"] * self.gravity_torques(q, g_base)
        return q

    def q_rep_from_true(self, q_true, g_base):
        tau = self.gravity_torques(q_true, g_base) if np.any(self.err["compliance"] != 0) else 0.0
        return (q_true - self.err["offset"] - self.err["compliance"] * tau) / (1 + self.err["scale"])


def ik(chain, p_target, d_target, q_start, tol=1e-11, iters=300):
    """Damped least squares on the TRUE chain over q_true: tip at p_target, flange z along
    d_target (roll free). Returns (q_true, pos_err, axis_err)."""
    q = q_start.copy()
    lo, hi = chain.robot.lower, chain.robot.upper
    lam = 1e-2
    for it in range(iters):
        axes, origins, p, r = chain.pose(q)
        z = r[:, 2]
        ep = p_target - p
        eo = cross3(z, d_target)
        err = np.concatenate([ep, 0.3 * eo])
        en = np.linalg.norm(ep)
        if en < tol and np.linalg.norm(eo) < 1e-9:
            return q, en, np.linalg.norm(eo)
        if it == 80 and en > 1e-3:
            break  # not converging from this start
        jp = cross_rows(axes, p - origins).T
        proj = np.eye(3) - np.outer(z, z)
        jo = 0.3 * proj @ axes.T
        jac = np.vstack([jp, jo])
        lam_eff = lam if en > 1e-4 else 1e-6
        dq = jac.T @ np.linalg.solve(jac @ jac.T + lam_eff ** 2 * np.eye(6), err)
        n = np.linalg.norm(dq)
        if n > 0.3:
            dq *= 0.3 / n
        q = np.clip(q + dq, lo + math.radians(1), hi - math.radians(1))
    axes, origins, p, r = chain.pose(q)
    return q, np.linalg.norm(p_target - p), np.linalg.norm(cross3(r[:, 2], d_target))


def solve_point(chain, p_target, d_target, rng, g_base, restarts=25):
    """True joint angles reaching p_target head-on, within limits (2 deg margin), or None."""
    robot = chain.robot
    margin = math.radians(2.0)
    for k in range(restarts):
        q0 = np.zeros(robot.dof)
        # Shoulder towards the target, arm bent, random wrist; then random restarts.
        q0[0] = math.atan2(p_target[1], p_target[0])
        spread = 0.4 if k == 0 else 1.2
        q0[1:] = rng.uniform(-spread, spread, robot.dof - 1)
        q0 = np.clip(q0, robot.lower + margin, robot.upper - margin)
        q, ep, eo = ik(chain, p_target, d_target, q0)
        if ep < 1e-9 and eo < 1e-6:
            q_rep = chain.q_rep_from_true(q, g_base)
            if np.all(q_rep > robot.lower + margin) and np.all(q_rep < robot.upper - margin):
                # Avoid near-singular postures (wrist straight): keep the solution well-conditioned.
                axes, origins, p, _ = chain.pose(q)
                jp = cross_rows(axes, p - origins).T
                if np.linalg.svd(jp, compute_uv=False)[-1] > 0.05:
                    return q
    return None


# ----------------------------------------------------------------------------- cell

MOUNTS = {
    # Table 1's placements (cells/*.toml), varied per session below.
    "floor-floor": ((37.9, 1476.5, 54.5), (-0.001, 0.001, -44.5), "floor"),
    "floor-wall": ((1303.3, -102.3, 1386.3), (180.0, 89.874, -179.997), "wall"),
    "floor-ceiling": ((1500.1, 500.0, 1499.9), (0.0, 180.001, 0.001), "ceiling"),
}


def make_placement(mounts, rng):
    """b1_from_b2 (R, t in m): a Table 1 placement turned about b1's vertical and about robot 2's
    own base z (floor: yaw, wall: roll in the wall, ceiling: yaw), which keeps the mount family."""
    xyz, zyz, mount = MOUNTS[mounts]
    r0 = rot_zyz(*[math.radians(a) for a in zyz])
    t0 = np.array(xyz) / 1000.0
    gamma = math.radians(rng.uniform(-25, 25))
    psi = math.radians(rng.uniform(-40, 40))
    r = rot_z(gamma) @ r0 @ rot_z(psi)
    t = rot_z(gamma) @ t0 + rng.normal(0, 0.03, 3)
    return r, t, mount


# ----------------------------------------------------------------------------- effects

KINDS = ["joint_offset", "link_length", "tip_offset", "mount_tilt", "compliance", "joint_scale"]
UNITS = {"joint_offset": "deg", "link_length": "mm", "tip_offset": "mm", "mount_tilt": "deg",
         "compliance": "deg/(kN·m)", "joint_scale": "ratio"}


def draw_effect(kind, dof, rng, robot=None):
    robot = robot if robot is not None else int(rng.integers(1, 3))
    d = dof[robot - 1]
    sign = 1.0 if rng.random() < 0.5 else -1.0
    e = dict(kind=kind, robot=robot, joint=None, axis=None, unit=UNITS[kind])
    if kind == "joint_offset":
        e["joint"] = int(rng.integers(1, d + 1))
        e["value"] = sign * rng.uniform(0.05, 0.3)
    elif kind == "link_length":
        e["joint"] = int(rng.integers(1, d + 1))
        e["axis"] = "xyz"[int(rng.integers(0, 3))]
        e["value"] = sign * rng.uniform(0.5, 3.0)
    elif kind == "tip_offset":
        e["axis"] = "xyz"[int(rng.integers(0, 3))]
        e["value"] = sign * rng.uniform(0.5, 3.0)
    elif kind == "mount_tilt":
        e["axis"] = "xy"[int(rng.integers(0, 2))]
        e["value"] = sign * rng.uniform(0.05, 0.3)
    elif kind == "compliance":
        # Joints 2-3 carry the large gravity torques; others are drawn too (often invisible).
        e["joint"] = int(rng.integers(1, d + 1))
        e["value"] = sign * rng.uniform(0.1, 1.0)
    elif kind == "joint_scale":
        e["joint"] = int(rng.integers(1, d + 1))
        e["value"] = sign * rng.uniform(2e-4, 1e-3)
    return e


def apply_effects(effects, dofs):
    errs = [zero_errors(dofs[0]), zero_errors(dofs[1])]
    for e in effects:
        er = errs[e["robot"] - 1]
        j = e["joint"] - 1 if e["joint"] else None
        ax = "xyz".index(e["axis"]) if e["axis"] else None
        v = e["value"]
        if e["kind"] == "joint_offset":
            er["offset"][j] += math.radians(v)
        elif e["kind"] == "joint_scale":
            er["scale"][j] += v
        elif e["kind"] == "link_length":
            er["dxyz"][j][ax] += v / 1000.0
        elif e["kind"] == "tip_offset":
            er["tip"][ax] += v / 1000.0
        elif e["kind"] == "mount_tilt":
            er["mount"] = er["mount"] @ rot_axis(np.eye(3)[ax], math.radians(v))
        elif e["kind"] == "compliance":
            er["compliance"][j] += math.radians(v) / 1000.0  # deg/(kN*m) -> rad/(N*m)
    return errs


# ----------------------------------------------------------------------------- session

def parse_effect(text):
    """`kind,robot,joint,axis,value` (joint/axis may be empty), e.g. `joint_offset,2,3,,0.2`."""
    kind, robot, joint, axis, value = text.split(",")
    return dict(kind=kind, robot=int(robot), joint=int(joint) if joint else None,
                axis=axis or None, unit=UNITS[kind], value=float(value))


def generate(seed, category, mounts, n, sigma_mm, out_dir, spread=None, rng=None, effects=None,
             noise_seed=None):
    """One session. The alignment noise draws from its own stream when `noise_seed` is given, so
    replicates with the same `seed` share the design (teach points, postures) and differ only in
    the noise."""
    rng = rng if rng is not None else np.random.default_rng(seed)
    rng_eps = np.random.default_rng(noise_seed) if noise_seed is not None else rng
    r1 = Robot(os.path.join(ROOT, "robots", "va1400.urdf"))
    r2 = Robot(os.path.join(ROOT, "robots", "hp20.urdf"))
    dofs = (r1.dof, r2.dof)
    tip1 = np.array([0.0, 0.0, 0.150])
    tip2 = np.array([0.0, 0.0, 0.120])
    if rng.random() < 0.5:  # sometimes an off-axis pin
        tip1 = np.array([rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02), rng.uniform(0.12, 0.2)])
        tip2 = np.array([rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02), rng.uniform(0.1, 0.18)])
    tip1, tip2 = np.round(tip1 * 1000, 1) / 1000, np.round(tip2 * 1000, 1) / 1000
    rx, tx, mount2 = make_placement(mounts, rng)
    # The cell file states angles with 6 decimals: use exactly what is written.
    xyz_mm = np.round(tx * 1000, 4)
    zyz_deg = np.round(np.degrees(zyz_from(rx)), 6)
    rx = rot_zyz(*np.radians(zyz_deg))
    tx = xyz_mm / 1000.0
    if effects is not None:
        pass
    elif category == "noise":
        effects = []
    elif category == "two_effects":
        k1, k2 = rng.choice([k for k in KINDS if k != "mount_tilt"], 2, replace=True)
        effects = [draw_effect(k1, dofs, rng)]
        while True:
            e2 = draw_effect(k2, dofs, rng)
            if (e2["kind"], e2["robot"], e2["joint"], e2["axis"]) != tuple(effects[0][k] for k in ("kind", "robot", "joint", "axis")):
                break
        effects.append(e2)
    else:
        effects = [draw_effect(category, dofs, rng)]
    errs = apply_effects(effects, dofs)
    g1 = np.array([0.0, 0.0, -G])
    g2 = rx.T @ g1
    c1_true, c2_true = Chain(r1, tip1, errs[0]), Chain(r2, tip2, errs[1])
    c1_nom, c2_nom = Chain(r1, tip1), Chain(r2, tip2)
    # Teach points: a random cube around the midpoint of the shoulders (joint-2 origins at q=0).
    sh1 = np.array([0.15, 0, 0.45])
    sh2 = rx @ np.array([0.15, 0, 0.505]) + tx
    centre = 0.5 * (sh1 + sh2)
    side = spread if spread is not None else rng.uniform(0.6, 1.0)
    d0 = (sh2 - sh1) / np.linalg.norm(sh2 - sh1)
    rows, clean = [], []
    attempts = 0
    while len(rows) < n:
        attempts += 1
        if attempts > 40 * n:
            raise RuntimeError(f"seed {seed}: could not place {n} points (got {len(rows)})")
        p = centre + rng.uniform(-side / 2, side / 2, 3)
        # Head-on direction: the shoulder line, turned up to 25 deg at random.
        d = d0 + rng.normal(0, 0.25, 3)
        d /= np.linalg.norm(d)
        eps = rng_eps.normal(0, sigma_mm / 1000.0, 3)
        q1t = solve_point(c1_true, p, d, rng, g1)
        if q1t is None:
            continue
        p2_b2 = rx.T @ (p + eps - tx)
        q2t = solve_point(c2_true, p2_b2, rx.T @ (-d), rng, g2)
        if q2t is None:
            continue
        q1r = c1_true.q_rep_from_true(q1t, g1)
        q2r = c2_true.q_rep_from_true(q2t, g2)
        # Consistency of the true map (fixed point of compliance) to 1e-9 m.
        assert np.linalg.norm(c1_true.tip_pos(c1_true.q_true_from_rep(q1r, g1)) - p) < 1e-8
        q1d = np.round(np.degrees(q1r), 3)
        q2d = np.round(np.degrees(q2r), 3)
        n1 = c1_nom.tip_pos(np.radians(q1d))
        n2 = c2_nom.tip_pos(np.radians(q2d))
        rows.append((q1d, q2d, n1 * 1000, n2 * 1000))
        clean.append(dict(p=p, q1r=q1r, q2r=q2r))
    # Signal of each effect alone (and all together) at these postures, noise-free: the RSS of a
    # rigid fit of the nominal readings when the true tips meet exactly, over sigma^2.
    def signal(effs):
        e1, e2 = apply_effects(effs, dofs)
        ca, cb = Chain(r1, tip1, e1), Chain(r2, tip2, e2)
        a, b = [], []
        for c in clean:
            t1 = ca.tip_pos(ca.q_true_from_rep(c["q1r"], g1))
            t2 = cb.tip_pos(cb.q_true_from_rep(c["q2r"], g2))
            m1 = c1_nom.tip_pos(c["q1r"])
            m2 = c2_nom.tip_pos(c["q2r"])
            a.append(c["p"] + (m1 - t1))
            b.append(rx.T @ (c["p"] - tx) + (m2 - t2))
        a, b = np.array(a), np.array(b)
        r, t = kabsch(a, b)
        rss = float(((a - (b @ r.T + t)) ** 2).sum())
        return math.sqrt(rss) / (sigma_mm / 1000.0)
    for e in effects:
        e["snr"] = signal([e])
    truth = dict(seed=seed, category=category, mounts=mounts, n_points=n, sigma_mm=sigma_mm,
                 spread_m=side, effects=effects, snr_all=signal(effects) if effects else 0.0,
                 b1_from_b2=dict(xyz_mm=xyz_mm.tolist(), zyz_deg=zyz_deg.tolist()),
                 tip1_mm=(tip1 * 1000).tolist(), tip2_mm=(tip2 * 1000).tolist())
    os.makedirs(out_dir, exist_ok=True)
    write_cell(os.path.join(out_dir, "cell.toml"), out_dir, mount2, tip1, tip2, xyz_mm, zyz_deg,
               sigma_mm, centre)
    write_session(os.path.join(out_dir, "session.csv"), rows, dofs)
    with open(os.path.join(out_dir, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    return truth


def write_cell(path, out_dir, mount2, tip1, tip2, xyz_mm, zyz_deg, sigma_mm, centre):
    rel = lambda f: os.path.relpath(os.path.join(ROOT, "robots", f), out_dir)
    f3 = lambda v: "[" + ", ".join(f"{x:.6f}" for x in v) + "]"
    text = f"""# Independent generator (tools/independent/gen_session.py). Lengths mm, angles degrees.
[robot1]
urdf = "{rel('va1400.urdf')}"
mount = "floor"
tip_mm = {f3(tip1 * 1000)}

[robot2]
urdf = "{rel('hp20.urdf')}"
mount = "{mount2}"
tip_mm = {f3(tip2 * 1000)}

[b1_from_b2]
xyz_mm = {f3(xyz_mm)}
zyz_deg = {f3(zyz_deg)}

[noise]
alignment_mm = {sigma_mm}
repeatability_mm = 0.0
encoder_resolution_deg = {ENCODER_DEG}

[teach]
centre_mm = {f3(centre * 1000)}
"""
    with open(path, "w") as f:
        f.write(text)


def write_session(path, rows, dofs):
    head = ["point"] + [f"r1_q{k}_deg" for k in range(1, dofs[0] + 1)] + \
        [f"r2_q{k}_deg" for k in range(1, dofs[1] + 1)] + \
        ["r1_x_mm", "r1_y_mm", "r1_z_mm", "r2_x_mm", "r2_y_mm", "r2_z_mm"]
    with open(path, "w") as f:
        f.write(",".join(head) + "\n")
        for i, (q1, q2, n1, n2) in enumerate(rows):
            vals = list(q1) + list(q2) + list(n1) + list(n2)
            f.write(f"{i + 1}," + ",".join(f"{v:.6f}" for v in vals) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--category", default="noise", choices=["noise", "two_effects"] + KINDS)
    ap.add_argument("--mounts", default="floor-wall", choices=list(MOUNTS))
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--sigma-mm", type=float, default=0.3)
    ap.add_argument("--effect", action="append",
                    help="a given effect instead of a random one: kind,robot,joint,axis,value (repeatable)")
    a = ap.parse_args()
    effects = [parse_effect(e) for e in a.effect] if a.effect else None
    t = generate(a.seed, a.category, a.mounts, a.n, a.sigma_mm, a.out, effects=effects)
    json.dump(t, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
