#!/usr/bin/env bash
# Stock robots the project did not write, for `sim-cell oracle` (issue 20, item 4; BENCHMARKS.md):
# the UR10, UR5 and Franka Panda URDFs of the `example-robot-data` package (BSD-3-Clause, its
# LICENSE files say which description each robot comes from), taken from its PyPI wheel by pip,
# and three two-robot cells of them written beside the URDFs:
#   ur10-ur5.toml      UR10 and UR5 on the floor 1.2 m apart, facing each other
#   ur5-ur5.toml       two UR5 on the floor 1.0 m apart, facing each other
#   panda-panda.toml   two Pandas on one table 0.9 m apart, facing each other
# Usage: tools/prior-bench/stock_cells.sh OUT_DIR   (then sim-cell oracle --cell OUT_DIR/ur10-ur5.toml …)
set -euo pipefail
out=${1:?usage: stock_cells.sh OUT_DIR}
mkdir -p "$out/wheel"
python3 -m pip download --quiet --no-deps example-robot-data==6.0.0 -d "$out/wheel"
share=cmeel.prefix/share/example-robot-data/robots
python3 - "$out" "$share" <<'PY'
import glob, os, re, sys, zipfile
out, share = sys.argv[1], sys.argv[2]
wheel = glob.glob(os.path.join(out, "wheel", "example_robot_data-*.whl"))[0]
want = {
    "ur10.urdf": f"{share}/ur_description/urdf/ur10_robot.urdf",
    "ur5.urdf": f"{share}/ur_description/urdf/ur5_robot.urdf",
    "panda.urdf": f"{share}/panda_description/urdf/panda.urdf",
    "LICENSE-example-robot-data": "example_robot_data-6.0.0.dist-info/licenses/LICENSE",
}
with zipfile.ZipFile(wheel) as z:
    for name, member in want.items():
        data = z.read(member)
        if name.endswith(".urdf"):
            # Already expanded by xacro; the leftover namespace declaration is all that is left
            # of it, and handclasp refuses any file that declares xmlns:xacro.
            data = re.sub(rb'\s+xmlns:xacro="[^"]*"', b"", data)
        with open(os.path.join(out, name), "wb") as f:
            f.write(data)
PY
cell() { # name urdf1 tool1 urdf2 tool2 x_mm yaw_deg centre tip_mm
  cat > "$out/$1.toml" <<TOML
# $1: stock robots of example-robot-data (tools/prior-bench/stock_cells.sh), facing each other.
[robot1]
urdf = "$2"
tool_link = "$3"
mount = "floor"
tip_mm = [0.0, 0.0, $9]

[robot2]
urdf = "$4"
tool_link = "$5"
mount = "floor"
tip_mm = [0.0, 0.0, $9]

[b1_from_b2]
xyz_mm = [$6, 0.0, 0.0]
zyz_deg = [$7, 0.0, 0.0]

[noise]
alignment_mm = 0.3
repeatability_mm = 0.03
encoder_resolution_deg = 0.001

[teach]
centre_mm = [$8]
TOML
}
cell ur10-ur5 ur10.urdf tool0 ur5.urdf tool0 1200.0 180.0 "600.0, 0.0, 400.0" 100.0
cell ur5-ur5 ur5.urdf tool0 ur5.urdf tool0 1000.0 180.0 "500.0, 0.0, 350.0" 100.0
cell panda-panda panda.urdf panda_link8 panda.urdf panda_link8 900.0 180.0 "450.0, 0.0, 400.0" 100.0
echo "wrote $out/ur10-ur5.toml $out/ur5-ur5.toml $out/panda-panda.toml"
