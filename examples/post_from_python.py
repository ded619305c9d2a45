"""Post a CL file from Python and look at the result.

Run from the project root: ``python examples/post_from_python.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from urdfpost import PostOptions, load_machine, post, read_cl
from urdfpost.kinematics import inverse, tip_and_axis

HERE = Path(__file__).parent

machine = load_machine("dmu50")  # a shipped machine, or a path to any URDF
print(f"{machine.name}: {machine.family}, axes {' '.join(machine.axis_names)}")

# every inverse-kinematics branch of one pose, checked with the forward kinematics
tip = np.array([[10.0, -5.0, 20.0]])
axis = np.array([[0.3, 0.2, 0.9]]) / np.linalg.norm([0.3, 0.2, 0.9])
ik = inverse(machine, tip, axis, tool_length=100.0)
for b in np.flatnonzero(ik.valid[0]):
    q = ik.q[0, b]
    got_tip, got_axis = tip_and_axis(machine, q, tool_length=100.0)
    print(
        f"branch {b}: {np.round(q, 3)}  tip error {np.linalg.norm(got_tip - tip):.1e} mm, "
        f"axis error {np.linalg.norm(got_axis - axis):.1e}"
    )

# post the bundled dome job in machine coordinates for a Siemens control
toolpath = read_cl(HERE / "dome.apt")
result = post(toolpath, machine, PostOptions(controller="siemens", tcp=False))
print(result.verification.summary(toolpath.units))
print("\n".join(result.text.splitlines()[:12]))
