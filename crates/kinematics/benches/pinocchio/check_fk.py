"""Cross-check of `handclasp fk` against pinocchio on both shipped URDFs (20 seeded random joint
vectors each, tip (10, -20, 150) mm). Prints the largest position (mm) and rotation-entry
differences. Needs `pip install pin` and a built `handclasp` (cargo build -p handclasp).

Run from the workspace root: python3 crates/kinematics/benches/pinocchio/check_fk.py
"""
import json
import subprocess

import numpy as np
import pinocchio as pin

HANDCLASP = "target/debug/handclasp"
rng = np.random.default_rng(1)
worst_mm, worst_r = 0.0, 0.0
for robot in ["hp20", "va1400"]:
    urdf = f"robots/{robot}.urdf"
    model = pin.buildModelFromUrdf(urdf)
    data = model.createData()
    fid = model.getFrameId("tool0")
    for _ in range(20):
        lo = np.maximum(model.lowerPositionLimit, -3) * 0.95
        hi = np.minimum(model.upperPositionLimit, 3) * 0.95
        q = rng.uniform(lo, hi)
        pin.forwardKinematics(model, data, q)
        pin.updateFramePlacement(model, data, fid)
        placement = data.oMf[fid]
        p_mm = placement.act(np.array([0.01, -0.02, 0.15])) * 1e3
        q_deg = ",".join(repr(float(np.degrees(x))) for x in q)
        out = subprocess.run(
            [HANDCLASP, "fk", "--robot", urdf, "--q-deg", q_deg, "--tip-mm", "10,-20,150", "--json"],
            capture_output=True, text=True, check=True,
        )
        fk = json.loads(out.stdout)
        worst_mm = max(worst_mm, np.max(np.abs(np.array(fk["xyz_mm"]) - p_mm)))
        worst_r = max(worst_r, np.max(np.abs(np.array(fk["rotation"]) - placement.rotation)))
print(f"max |xyz difference| {worst_mm:.3e} mm, max |rotation entry difference| {worst_r:.3e}")
