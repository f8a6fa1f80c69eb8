#!/usr/bin/env python3
"""Independent check of `handclasp export` (issue 23): the same conversions with SciPy.

Shares no code with the Rust crates. For each cell TOML given it
1. reads the cell's placement ([b1_from_b2] xyz_mm, zyz_deg: R = Rz(phi)*Ry(theta)*Rz(psi),
   SciPy's intrinsic 'ZYZ') with tomllib;
2. converts it with scipy.spatial.transform.Rotation:
   KUKA A, B, C       = as_euler('ZYX')  (intrinsic z, y', x'': R = Rz(A)*Ry(B)*Rx(C))
   Fanuc W, P, R      = as_euler('xyz')  (extrinsic x, then y, then z: R = Rz(R)*Ry(P)*Rx(W))
   Yaskawa Rx, Ry, Rz = as_euler('xyz')  (same fixed-axis order)
   ABB q1..q4, ROS qx..qw = as_quat(canonical=True) (w >= 0), reordered w,x,y,z / x,y,z,w;
3. runs `handclasp export --cell CELL --to TMP --json`, then parses every written file with its
   own small parsers (regular expressions and xml.etree; the cell URDF also with yourdfpy if it is
   installed: world -> robot2_base_link, and both tool links reachable from world) and the JSON;
4. prints, per cell and target, the largest translation difference (um), the rotation angle
   between SciPy's rotation and the file's (urad), and the largest angle difference (deg; not
   compared within 1e-6 rad of gimbal lock, where only a sum of angles is defined and SciPy's
   lock threshold differs from handclasp's), and exits 1 if any exceeds 1 um / 1 urad / 1e-6 deg.

Usage: python3 tools/export_check.py --handclasp target/release/handclasp cells/*.toml [CELL ...]
Needs numpy and scipy (>= 1.11, for canonical quaternions); yourdfpy optional:
  python3 -m venv /tmp/hc && /tmp/hc/bin/pip install numpy scipy yourdfpy
"""

import argparse
import json
import math
import re
import subprocess
import sys
import tempfile
import tomllib
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

TOL_UM = 1.0
TOL_URAD = 1.0
TOL_DEG = 1e-6
# Within this of B = +-90 deg (rad) the angle triple is not compared, only the rotation.
LOCK_BAND_RAD = 1e-6


def cell_placement(path):
    with open(path, "rb") as f:
        cell = tomllib.load(f)
    p = cell["b1_from_b2"]
    rot = Rotation.from_euler("ZYZ", p["zyz_deg"], degrees=True)
    return np.array(p["xyz_mm"], dtype=float), rot


def independent(t_mm, rot):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # SciPy warns at gimbal lock; handled by the lock band.
        abc = rot.as_euler("ZYX", degrees=True)
        wpr = rot.as_euler("xyz", degrees=True)
    x, y, z, w = rot.as_quat(canonical=True)
    t_m = t_mm / 1e3
    return {
        "abb": dict(x_m=t_m[0], y_m=t_m[1], z_m=t_m[2], q1=w, q2=x, q3=y, q4=z),
        "kuka": dict(x_mm=t_mm[0], y_mm=t_mm[1], z_mm=t_mm[2], a_deg=abc[0], b_deg=abc[1], c_deg=abc[2]),
        "fanuc": dict(x_mm=t_mm[0], y_mm=t_mm[1], z_mm=t_mm[2], w_deg=wpr[0], p_deg=wpr[1], r_deg=wpr[2]),
        "yaskawa": dict(x_mm=t_mm[0], y_mm=t_mm[1], z_mm=t_mm[2], rx_deg=wpr[0], ry_deg=wpr[1], rz_deg=wpr[2]),
        "ros2": dict(x_m=t_m[0], y_m=t_m[1], z_m=t_m[2], qx=x, qy=y, qz=z, qw=w),
    }


def placement_of(target, v):
    """(translation mm, Rotation) of one target's numbers, by the target's convention."""
    if target in ("abb", "ros2"):
        t = np.array([v["x_m"], v["y_m"], v["z_m"]]) * 1e3
        if target == "abb":
            q = [v["q2"], v["q3"], v["q4"], v["q1"]]
        else:
            q = [v["qx"], v["qy"], v["qz"], v["qw"]]
        return t, Rotation.from_quat(q)
    t = np.array([v["x_mm"], v["y_mm"], v["z_mm"]])
    if target == "kuka":
        return t, Rotation.from_euler("ZYX", [v["a_deg"], v["b_deg"], v["c_deg"]], degrees=True)
    if target == "fanuc":
        return t, Rotation.from_euler("xyz", [v["w_deg"], v["p_deg"], v["r_deg"]], degrees=True)
    return t, Rotation.from_euler("xyz", [v["rx_deg"], v["ry_deg"], v["rz_deg"]], degrees=True)


NUM = r"([-+0-9.eE]+)"


def parse_files(d):
    """Each file's numbers, parsed here (not by handclasp)."""
    out = {}
    text = (d / "abb_moc_base_frame.cfg").read_text()
    body = text.split('-name "ROB_2"', 1)[1]
    get = lambda key: float(re.search(r"-" + key + r"\s+" + NUM, body).group(1))
    out["abb"] = dict(
        x_m=get("base_frame_pos_x"), y_m=get("base_frame_pos_y"), z_m=get("base_frame_pos_z"),
        q1=get("base_frame_orient_u0"), q2=get("base_frame_orient_u1"),
        q3=get("base_frame_orient_u2"), q4=get("base_frame_orient_u3"))
    text = (d / "kuka_robroot.dat").read_text()
    m = re.search(r"FRAME \$ROBROOT=\{X " + NUM + ",Y " + NUM + ",Z " + NUM + ",A " + NUM + ",B " + NUM + ",C " + NUM + r"\}", text)
    out["kuka"] = dict(zip(["x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"], map(float, m.groups())))

    def listing(name, comment, keys, names):
        vals = {}
        for line in (d / name).read_text().splitlines():
            if line.startswith(comment) or ":" not in line:
                continue
            k, rest = line.split(":", 1)
            vals[k.strip()] = float(rest.split()[0])
        return {n: vals[k] for k, n in zip(keys, names)}

    out["fanuc"] = listing("fanuc_user_frame.txt", "!", ["X", "Y", "Z", "W", "P", "R"],
                           ["x_mm", "y_mm", "z_mm", "w_deg", "p_deg", "r_deg"])
    out["yaskawa"] = listing("yaskawa_user_frame.txt", "'", ["X", "Y", "Z", "Rx", "Ry", "Rz"],
                             ["x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg"])
    node = ET.parse(d / "b1_from_b2.launch.xml").getroot().find("node")
    args = node.get("args").split()
    flag = lambda f: float(args[args.index(f) + 1])
    out["ros2 launch"] = dict(x_m=flag("--x"), y_m=flag("--y"), z_m=flag("--z"),
                              qx=flag("--qx"), qy=flag("--qy"), qz=flag("--qz"), qw=flag("--qw"))
    props = {p.get("name"): p.get("value") for p in ET.parse(d / "b1_from_b2.xacro").getroot()
             if p.tag.endswith("property")}
    xyz = [float(props["b1_from_b2_" + k]) for k in "xyz"]
    rpy = [float(props["b1_from_b2_" + k]) for k in ("roll", "pitch", "yaw")]
    out["ros2 xacro"] = (np.array(xyz) * 1e3, Rotation.from_euler("xyz", rpy))
    urdf = ET.parse(d / "cell.urdf").getroot()
    mount = [j for j in urdf.findall("joint") if j.get("name") == "robot2_mount"][0]
    origin = mount.find("origin")
    xyz = [float(s) for s in origin.get("xyz").split()]
    rpy = [float(s) for s in origin.get("rpy").split()]
    out["ros2 urdf"] = (np.array(xyz) * 1e3, Rotation.from_euler("xyz", rpy))
    try:
        import yourdfpy
    except ImportError:
        yourdfpy = None
        print("note: yourdfpy is not installed; cell.urdf is read with xml.etree only", file=sys.stderr)
    if yourdfpy is not None:
        robot = yourdfpy.URDF.load(str(d / "cell.urdf"), load_meshes=False, build_collision_scene_graph=False)
        m = robot.get_transform("robot2_base_link", "world")
        for link in ("robot1_tool0", "robot2_tool0", "robot1_tip", "robot2_tip"):
            if link in robot.link_map:
                robot.get_transform(link, "world")  # raises if not reachable
        out["ros2 urdf (yourdfpy)"] = (m[:3, 3] * 1e3, Rotation.from_matrix(m[:3, :3]))
    return out


def compare(target, ref_t, ref_rot, ref_vals, got):
    if isinstance(got, tuple):
        t, rot, vals = got[0], got[1], None
    else:
        t, rot = placement_of(target.split()[0], got)
        vals = got
    dt_um = float(np.max(np.abs(t - ref_t))) * 1e3
    drot_urad = float((ref_rot.inv() * rot).magnitude()) * 1e6
    ddeg = None
    if vals is not None and target.split()[0] in ("kuka", "fanuc", "yaskawa"):
        b = ref_vals.get("b_deg", ref_vals.get("p_deg", ref_vals.get("ry_deg")))
        if abs(abs(b) - 90.0) > math.degrees(LOCK_BAND_RAD):
            ddeg = max(abs((vals[k] - ref_vals[k] + 180.0) % 360.0 - 180.0)
                       for k in vals if k.endswith("_deg"))
    return dt_um, drot_urad, ddeg


def pendant_rounding(cells, decimals):
    """The cost of typing the three-angle formats rounded to `decimals` decimals."""
    print(f"{'cell':<28} {'target':<8} {'dt_um':>8} {'drot_urad':>10} {'at_1.5m_um':>11}")
    for cell in cells:
        t, rot = cell_placement(cell)
        ref = independent(t, rot)
        for target in ("kuka", "fanuc", "yaskawa"):
            rounded = {k: round(v, decimals) for k, v in ref[target].items()}
            rt, rr = placement_of(target, rounded)
            dt = float(np.linalg.norm(rt - t)) * 1e3
            drot = float((rot.inv() * rr).magnitude())
            print(f"{Path(cell).name:<28} {target:<8} {dt:8.1f} {drot * 1e6:10.2f} {dt + drot * 1.5e6:11.1f}")
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--handclasp", required=True, help="the handclasp binary")
    ap.add_argument("cells", nargs="+", help="cell TOML files")
    ap.add_argument("--pendant-decimals", type=int, default=None,
                    help="also print what typing the KUKA/Fanuc/Yaskawa numbers rounded to this many "
                         "decimals (mm and deg) costs: rotation error and the error at 1.5 m")
    a = ap.parse_args()
    if a.pendant_decimals is not None:
        return pendant_rounding(a.cells, a.pendant_decimals)
    worst = [0.0, 0.0, 0.0]
    print(f"{'cell':<40} {'target':<22} {'dt_um':>10} {'drot_urad':>10} {'dangle_deg':>11}")
    for cell in a.cells:
        ref_t, ref_rot = cell_placement(cell)
        ref = independent(ref_t, ref_rot)
        with tempfile.TemporaryDirectory() as tmp:
            run = subprocess.run([a.handclasp, "export", "--cell", cell, "--to", tmp, "--json"],
                                 capture_output=True, text=True)
            if run.returncode != 0:
                print(f"{cell}: handclasp export failed:\n{run.stderr}", file=sys.stderr)
                return 1
            report = json.loads(run.stdout)
            checks = [(f"{k} json", report["formats"][k]) for k in ref]
            checks += list(parse_files(Path(tmp)).items())
            for name, got in checks:
                base = name.split()[0]
                dt, dr, dd = compare(name, ref_t, ref_rot, ref[base], got)
                worst = [max(worst[0], dt), max(worst[1], dr), max(worst[2], dd or 0.0)]
                dd_s = "lock" if dd is None and base in ("kuka", "fanuc", "yaskawa") else (
                    "" if dd is None else f"{dd:.2e}")
                print(f"{Path(cell).as_posix()[-40:]:<40} {name:<22} {dt:10.2e} {dr:10.2e} {dd_s:>11}")
    ok = worst[0] <= TOL_UM and worst[1] <= TOL_URAD and worst[2] <= TOL_DEG
    print(f"worst: {worst[0]:.2e} um, {worst[1]:.2e} urad, {worst[2]:.2e} deg "
          f"(limits {TOL_UM} um, {TOL_URAD} urad, {TOL_DEG} deg): {'AGREE' if ok else 'DISAGREE'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
