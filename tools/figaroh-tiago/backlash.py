#!/usr/bin/env python3
"""Exploratory probe of a backlash on FIGAROH's TIAGo training file (training file only; never a
held-out file): the gravity torque at each arm joint per pose from the URDF's inertials (nominal
kinematics, every link the joint carries), and, for a joint and backlash sizes b, cv.py's
leave-one-pose-out of a candidate with that joint's reading shifted by b/2 · sign(torque) (the
gear's play taken up on the side gravity pushes it to). b is scanned by the same CV that scores
it, so the figures are optimistic: a finding to pre-register a model on, not a model choice.

Usage: tools/figaroh-tiago/backlash.py [--data DIR] [--bin DIR] [--joint arm_6_joint]
       [--mrad 0,40,60] [--candidate "C0 incumbent"] [--per-pose]
"""
import argparse
import atexit
import csv
import math
import os
import shutil
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
TRAIN = "qualisys_2021-11-30_static_postures.csv"
URDF = "tiago_48_schunk.urdf"
ARM = [f"arm_{i}_joint" for i in range(1, 8)]
G_BASE = np.array([0.0, 0.0, -9.81])  # m/s², the base upright (the cell's floor mount)


def rot_rpy(r, p, y):
    """URDF fixed-axis roll, pitch, yaw: Rz(y)·Ry(p)·Rx(r)."""
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y),
                              math.sin(y))
    return (np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
            @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
            @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]]))


def floats(elem, key, default):
    return np.array([float(v) for v in (elem.get(key, default) if elem is not None
                                        else default).split()])


class Urdf:
    """The joints (origin, axis, type) and link inertials (mass, centre of mass) of a URDF."""

    def __init__(self, path):
        root = ET.parse(path).getroot()
        self.joints, self.children, self.inertials = {}, {}, {}
        for j in root.findall("joint"):
            o, a = j.find("origin"), j.find("axis")
            self.joints[j.get("name")] = dict(
                type=j.get("type"), parent=j.find("parent").get("link"),
                child=j.find("child").get("link"), xyz=floats(o, "xyz", "0 0 0"),
                rpy=floats(o, "rpy", "0 0 0"), axis=floats(a, "xyz", "1 0 0"))
        for name, j in self.joints.items():
            self.children.setdefault(j["parent"], []).append(name)
        for link in root.findall("link"):
            i = link.find("inertial")
            if i is not None and i.find("mass") is not None:
                self.inertials[link.get("name")] = (float(i.find("mass").get("value")),
                                                    floats(i.find("origin"), "xyz", "0 0 0"))
        parents = {j["parent"] for j in self.joints.values()}
        self.root = next(p for p in parents if p not in {j["child"] for j in self.joints.values()})

    def poses(self, q):
        """Every link's (R, t) in the root frame and every joint's (origin, axis), joints not in
        `q` at 0."""
        links, joints, stack = {self.root: (np.eye(3), np.zeros(3))}, {}, [self.root]
        while stack:
            parent = stack.pop()
            r, t = links[parent]
            for name in self.children.get(parent, []):
                j = self.joints[name]
                rj, tj = r @ rot_rpy(*j["rpy"]), t + r @ j["xyz"]
                v = q.get(name, 0.0)
                if j["type"] in ("revolute", "continuous"):
                    ax = j["axis"] / np.linalg.norm(j["axis"])
                    k = np.array([[0, -ax[2], ax[1]], [ax[2], 0, -ax[0]], [-ax[1], ax[0], 0]])
                    links[j["child"]] = (rj @ (np.eye(3) + math.sin(v) * k
                                               + (1 - math.cos(v)) * k @ k), tj)
                elif j["type"] == "prismatic":
                    links[j["child"]] = (rj, tj + rj @ (j["axis"] * v))
                else:
                    links[j["child"]] = (rj, tj)
                joints[name] = (tj, rj @ j["axis"])
                stack.append(j["child"])
        return links, joints

    def carried(self, link):
        out = [link]
        for name in self.children.get(link, []):
            out += self.carried(self.joints[name]["child"])
        return out

    def gravity_torque(self, q, joint):
        """The gravity torque about `joint`'s axis (N·m) of everything it carries."""
        links, joints = self.poses(q)
        origin, axis = joints[joint]
        tau = 0.0
        for link in self.carried(self.joints[joint]["child"]):
            if link in self.inertials:
                m, com = self.inertials[link]
                r, t = links[link]
                tau += axis @ np.cross(t + r @ com - origin, m * G_BASE)
        return tau


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default="../shared/data/figaroh-tiago")
    ap.add_argument("--bin", default="target/release")
    ap.add_argument("--joint", default="arm_6_joint")
    ap.add_argument("--mrad", default="0,40,60", help="backlash sizes b, mrad (comma-separated)")
    ap.add_argument("--candidate", default="C0 incumbent")
    ap.add_argument("--per-pose", action="store_true", help="each left-out pose's rms too")
    a = ap.parse_args()
    data = os.path.abspath(a.data)
    urdf = Urdf(os.path.join(data, URDF))
    rows = list(csv.DictReader(open(os.path.join(data, TRAIN))))
    joints_q = ["torso_lift_joint"] + ARM
    taus = [[urdf.gravity_torque({k: float(r[k]) for k in joints_q}, j) for j in ARM]
            for r in rows]
    print("gravity torque per arm joint over the training poses (N·m): joint, poses > 0, < 0, "
          "|τ| < 0.2, min, max")
    for i, j in enumerate(ARM):
        v = [t[i] for t in taus]
        print(f"  {j:12s} {sum(x > 0 for x in v):3d} {sum(x < 0 for x in v):3d} "
              f"{sum(abs(x) < 0.2 for x in v):3d} {min(v):8.3f} {max(v):8.3f}")
    col = ARM.index(a.joint)
    print(f"poses with {a.joint}'s torque > 0: "
          f"{[i + 1 for i, t in enumerate(taus) if t[col] > 0]}")
    tmp = tempfile.mkdtemp(prefix="tiago-backlash-")
    atexit.register(shutil.rmtree, tmp, True)  # leave nothing behind
    os.symlink(os.path.join(data, URDF), os.path.join(tmp, URDF))
    for b in [float(x) for x in a.mrad.split(",")]:
        with open(os.path.join(tmp, TRAIN), "w", newline="") as f:
            w = csv.DictWriter(f, list(rows[0].keys()))
            w.writeheader()
            for r, t in zip(rows, taus):
                r = dict(r)
                r[a.joint] = repr(float(r[a.joint]) + math.copysign(b / 2000.0, t[col]))
                w.writerow(r)
        out = subprocess.run(
            [sys.executable, os.path.join(HERE, "cv.py"), "--bin", a.bin, "--data", tmp,
             "--folds", str(len(rows)), "--only", a.candidate, "--per-fold"],
            capture_output=True, text=True)
        if out.returncode != 0:
            sys.exit(f"cv.py failed at b = {b} mrad:\n{out.stderr}")
        print(f"{a.joint} backlash {b:+.0f} mrad: {out.stdout.strip()}")
        if a.per_pose:
            print("  " + " ".join(line.split()[2] for line in out.stderr.splitlines()
                                  if line.startswith("fold ")))


if __name__ == "__main__":
    main()
