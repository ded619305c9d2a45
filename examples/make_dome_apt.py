"""Write ``examples/dome.apt`` (a five-axis finishing job on a dome, tool normal to the surface)
and ``examples/dome.stl`` (the part: the dome on a 4 mm base, for ``--stock``).

The passes run across a 30 mm radius dome at offsets y0 from its top, so the tool axis passes
through vertical (y0 = 0, an exact pole crossing) and near it (a near miss of arcsin(y0 / R)).
Run it again to regenerate both files: ``python examples/make_dome_apt.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

RADIUS = 30.0  # mm
OFFSETS = (-12.0, -6.0, -2.0, 0.0, 2.0, 6.0, 12.0)  # mm, pass offsets from the top
CLEARANCE = 15.0  # mm above the surface along the tool axis for links


def _goto(p: np.ndarray, v: np.ndarray) -> str:
    return "GOTO/{:.4f},{:.4f},{:.4f},{:.6f},{:.6f},{:.6f}".format(*p, *v)


def dome_records() -> list[str]:
    """APT records of the job."""
    out = [
        "PARTNO DOME FINISH",
        "UNITS/MM",
        "MULTAX/ON",
        "$$ 6 mm ball mill, tool normal to a 30 mm dome",
        "LOADTL/3",
        "CUTTER/6.0,3.0",
        "SPINDL/12000,CLW",
        "COOLNT/FLOOD",
    ]
    for k, y0 in enumerate(OFFSETS):
        half = np.sqrt(RADIUS**2 - y0**2) * 0.8
        xs = np.linspace(-half, half, 41)
        if k % 2:
            xs = xs[::-1]
        z = np.sqrt(RADIUS**2 - xs**2 - y0**2)
        pts = np.stack([xs, np.full_like(xs, y0), z], axis=1)
        axes = pts / RADIUS
        out.append(f"PPRINT PASS {k + 1} AT Y {y0:+.1f}")
        out.append("RAPID")
        out.append(_goto(pts[0] + CLEARANCE * axes[0], axes[0]))
        out.append("FEDRAT/MMPM,800")
        out.append(_goto(pts[0], axes[0]))
        out.append("FEDRAT/MMPM,2000")
        out += [_goto(p, v) for p, v in zip(pts[1:], axes[1:], strict=True)]
        out.append("FEDRAT/MMPM,3000")
        out.append(_goto(pts[-1] + CLEARANCE * axes[-1], axes[-1]))
    out += ["COOLNT/OFF", "SPINDL/OFF", "GOHOME", "END", "FINI"]
    return out


def dome_mesh(sections: int = 96, rings: int = 48) -> trimesh.Trimesh:
    """The part as a closed mesh in the workpiece frame, mm: the dome (its vertices on the
    sphere, so the facets lie inside it by at most the chord sag) on a base 4 mm deep, a little
    wider than the dome."""
    phi = np.linspace(0.0, 0.5 * np.pi, rings + 1)
    arc = np.stack([RADIUS * np.sin(phi), RADIUS * np.cos(phi)], axis=1)  # (r, z), top first
    base = [[RADIUS + 5.0, 0.0], [RADIUS + 5.0, -4.0], [0.0, -4.0]]
    profile = np.vstack([arc, base])[::-1]  # counterclockwise in (r, z): outward normals
    return trimesh.creation.revolve(profile, sections=sections)


if __name__ == "__main__":
    target = Path(__file__).with_name("dome.apt")
    target.write_text("\n".join(dome_records()) + "\n", encoding="utf-8")
    print(f"wrote {target}")
    mesh = dome_mesh()
    assert mesh.is_watertight and mesh.volume > 0
    mesh.export(Path(__file__).with_name("dome.stl"))
    print(f"wrote {target.with_suffix('.stl')} ({len(mesh.faces)} triangles)")
