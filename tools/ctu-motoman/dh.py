"""The CTU dual-arm Motoman model as data: standard DH tables of both arms and the end effectors.

Numbers: /work/shared/data/ctu-motoman/README.md ("Robot model"), which restates the model files of
ctu-vras/multirobot-calibration (commit a20f0454). Units: m, rad.
Convention: T_i = Rz(offset_i + q_i) · Tz(d_i) · Tx(a_i) · Rx(alpha_i); the base frame is at the
start of row TT (the common base of both arms); row TT is driven by the turntable E.
"""
import math

import numpy as np

PI = math.pi
# Rows S, L, U, R, B, T (identical for both arms): (a, d, alpha, offset).
ARM_ROWS = [
    (0.150, 1.4159, -PI / 2, 0.0),   # S
    (0.614, 0.0, PI, -PI / 2),       # L
    (0.200, 0.0, -PI / 2, 0.0),      # U
    (0.0, -0.640, PI / 2, 0.0),      # R
    (0.030, 0.0, PI / 2, -PI / 2),   # B
    (0.0, 0.200, 0.0, 0.0),          # T
]
JOINT_NAMES = ["s", "l", "u", "r", "b", "t"]
# Row TT: alpha = +15 deg (right), -15 deg (left); the README prints 0.26179939 = 15 deg to 8 digits.
TT_ROW = {
    "right": (0.0, -0.263, PI / 12, -PI / 2),
    "left": (0.0, -0.263, -PI / 12, -PI / 2),
}
# End-effector rows (fixed, joint value 0).
EE_MARKER = (0.0, 0.354, 0.0, 0.0)  # marker dodecahedron, both arms
EE_REFLECTOR = {
    "right": (0.045, 0.245, 0.0, -0.38),
    "left": (0.05, 0.25, 0.0, 0.0),
}


def dh(a, d, alpha, theta):
    """4x4 homogeneous Rz(theta)·Tz(d)·Tx(a)·Rx(alpha)."""
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([
        [ct, -st * ca, st * sa, a * ct],
        [st, ct * ca, -ct * sa, a * st],
        [0.0, sa, ca, d],
        [0.0, 0.0, 0.0, 1.0],
    ])


def ee_tip(row):
    """Tip offset of an EE row in the frame after row T (tool0), m."""
    return dh(row[0], row[1], row[2], row[3])[:3, 3].copy()
