"""CL jobs shared by the tests of the job around the tool path (tests/test_job.py), of the
process check of ``verify`` (tests/test_verify_process.py) and of the LinuxCNC interpreter
(tests/test_rs274.py), and the benchmark's hemisphere raster (tests/test_stream.py,
tests/test_faults.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def write_hemisphere(points: int, path: Path) -> Path:
    """The hemisphere raster of ``bench/make_large_cl.py`` (passes over and beside the pole),
    ``points`` CL points, written as APT to ``path``."""
    spec = importlib.util.spec_from_file_location("make_large_cl", ROOT / "bench/make_large_cl.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    written: Path = module.write_hemisphere(points, path)
    return written


def two_tools(first_feed: float = 800.0) -> str:
    """Two tools with spindle, coolant and two feeds (the first ``first_feed`` mm/min, then
    500). The second tool has no SPINDL of its own (the post restarts the spindle at the speed
    before the change) and starts with a feed move, not a rapid."""
    return f"""\
PARTNO TWO TOOLS
UNITS/MM
MULTAX/ON
LOADTL/1
SPINDL/9000,CLW
COOLNT/FLOOD
RAPID
GOTO/0,0,20,0,0,1
FEDRAT/MMPM,{first_feed:g}
GOTO/0,0,2,0,0,1
GOTO/20,0,2,0.258819,0,0.965926
GOTO/20,20,2,0.258819,0,0.965926
LOADTL/2
GOTO/-10,0,1,0,0.258819,0.965926
FEDRAT/MMPM,500
GOTO/-30,0,1,0,0.258819,0.965926
FINI
"""


#: :func:`two_tools` at its default feed.
TWO_TOOLS = two_tools()


def drilling_job(units: str = "MM", tilted: bool = False) -> str:
    """A drilling job of three canned cycles at flat holes: drilling (two holes, NX CLSF
    keyword form with a negative FEDTO, a dwell at the bottom), deep-hole pecking (two holes
    at another height), tapping by feed per revolution (one hole); with ``tilted``, a fourth
    cycle drills a hole whose tool axis leans 30 degrees about Y. Lengths in ``units`` ("MM"
    or "INCHES", the inch job being the mm one divided by 25.4)."""
    k = 25.4 if units == "INCHES" else 1.0

    def v(value: float) -> str:
        return f"{value / k:.6g}"

    feed = "IPM" if units == "INCHES" else "MMPM"
    per_rev = "IPR" if units == "INCHES" else "MMPR"
    tilted_cycle = f"""\
CYCLE/DRILL,FEDTO,{v(4)},{feed},{v(90)},RAPTO,{v(2)},RTRCTO,{v(8)}
GOTO/{v(40)},{v(-20)},{v(-2)},0.5,0,0.8660254
CYCLE/OFF
RAPID
GOTO/{v(60)},{v(-20)},{v(40)},0.5,0,0.8660254
"""
    return f"""\
PARTNO DRILLING
UNITS/{units}
MULTAX/ON
LOADTL/3
SPINDL/RPM,1200,CLW
COOLNT/FLOOD
RAPID
GOTO/{v(10)},{v(10)},{v(30)},0,0,1
CYCLE/DRILL,RAPTO,{v(2)},FEDTO,-{v(6)},RTRCTO,{v(10)},{feed},{v(150)},DWELL,0.5
GOTO/{v(10)},{v(10)},0,0,0,1
GOTO/{v(30)},{v(10)},0,0,0,1
CYCLE/OFF
CYCLE/DRILL,DEEP,FEDTO,{v(14)},INCR,{v(5)},{feed},{v(90)},CLEAR,{v(3)}
GOTO/{v(30)},{v(-10)},{v(-1)},0,0,1
GOTO/{v(10)},{v(-10)},{v(-1)},0,0,1
CYCLE/OFF
CYCLE/TAP,FEDTO,{v(10)},{per_rev},{v(1.25)},RAPTO,{v(4)}
GOTO/{v(20)},0,0,0,0,1
CYCLE/OFF
RAPID
GOTO/{v(20)},0,{v(30)},0,0,1
{tilted_cycle if tilted else ""}FINI
"""


def rotary_sweep(feed: float = 400.0, points: int = 48) -> str:
    """A cut with large rotary moves (issue 19): the tool tip goes along a line in X at Z=0
    while the tool axis, tilted 25 degrees from Z, turns 270 degrees about Z (the table's or
    head's C axis turns with it), then tilts back to Z along the last stretch. One feed,
    ``feed`` mm/min; ``points`` CL points on the turn."""
    import math

    lines = [
        "PARTNO ROTARY SWEEP",
        "UNITS/MM",
        "MULTAX/ON",
        "LOADTL/1",
        "SPINDL/8000,CLW",
        "RAPID",
    ]
    tilt = math.radians(25.0)

    def goto(x: float, y: float, z: float, i: float, j: float, k: float) -> str:
        return f"GOTO/{x:.4f},{y:.4f},{z:.4f},{i:.6f},{j:.6f},{k:.6f}"

    start = (math.sin(tilt), 0.0, math.cos(tilt))
    lines.append(goto(-20.0, 0.0, 10.0, *start))
    lines.append(f"FEDRAT/MMPM,{feed:g}")
    for n in range(points + 1):
        s = n / points
        phi = math.radians(270.0) * s
        axis = (math.sin(tilt) * math.cos(phi), math.sin(tilt) * math.sin(phi), math.cos(tilt))
        lines.append(goto(-20.0 + 30.0 * s, 5.0 * math.sin(math.pi * s), 0.0, *axis))
    for n in range(1, 9):
        s = n / 8
        t = tilt * (1.0 - s)
        axis = (0.0, -math.sin(t), math.cos(t))
        lines.append(goto(10.0 + 10.0 * s, 0.0, 0.0, *axis))
    lines += ["RAPID", goto(20.0, 0.0, 20.0, 0.0, 0.0, 1.0), "FINI", ""]
    return "\n".join(lines)


def arc_job() -> str:
    """A planar arc job (mm, fixed vertical tool): two quarter circles of radius 20 about the
    origin (counter-clockwise), a straight line, a quarter circle of radius 10 clockwise
    (normal -Z), a half circle of radius 10 in the ZX plane (normal -Y, down a wall), a
    straight line and a helical quarter circle (down 2 mm), each continued tangentially by
    the moves around it."""
    return """\
PARTNO ARC JOB
UNITS/MM
LOADTL/3
SPINDL/8000,CLW
RAPID
GOTO/20,0,10
FEDRAT/MMPM,600
GOTO/20,0,-1
CIRCLE/0,0,-1,0,0,1,20
GOTO/0,20,-1
CIRCLE/0,0,-1,0,0,1,20
GOTO/-20,0,-1
GOTO/-20,-10,-1
CIRCLE/-10,-10,-1,0,0,1,10
GOTO/-10,-20,-1
FEDRAT/MMPM,400
GOTO/0,-20,-1
CIRCLE/0,-30,-1,0,0,-1,10
GOTO/10,-30,-1
CIRCLE/20,-30,-1,0,-1,0,10
GOTO/30,-30,-1
GOTO/30,-20,-1
CIRCLE/20,-20,-1,0,0,1,10
GOTO/20,-10,-3
RAPID
GOTO/20,-10,10
FINI
"""


def cutcom_job() -> str:
    """A pocket wall with cutter radius compensation (mm, vertical tool): ``CUTCOM/LEFT``
    before a straight entry move, a square with a rounded corner, ``CUTCOM/OFF`` before the
    straight exit move."""
    return """\
PARTNO CUTCOM JOB
UNITS/MM
LOADTL/3
SPINDL/8000,CLW
RAPID
GOTO/-20,-20,10
FEDRAT/MMPM,500
GOTO/-20,-20,-2
CUTCOM/LEFT,XYPLAN
GOTO/-10,-10,-2
GOTO/10,-10,-2
GOTO/10,5,-2
CIRCLE/5,5,-2,0,0,1,5
GOTO/5,10,-2
GOTO/-10,10,-2
GOTO/-10,-10,-2
CUTCOM/OFF
GOTO/-20,-20,-2
RAPID
GOTO/-20,-20,10
FINI
"""


def indexed_job() -> str:
    """A 3+2 job: a flat cut, then two operations at a fixed tilt, each entered and left at a
    rapid: the first with the tool axis leaning 30 degrees about Y (a pocket wall's three
    cuts), the second leaning 20 degrees about -X with a slot and a drilling cycle at two
    holes of different heights along its axis (two cycle blocks in its plane)."""
    one = "0.5,0,0.8660254"
    two = "0,-0.3420201,0.9396926"
    return f"""\
PARTNO INDEXED
UNITS/MM
MULTAX/ON
LOADTL/1
SPINDL/RPM,8000,CLW
COOLNT/FLOOD
RAPID
GOTO/0,0,30,0,0,1
FEDRAT/MMPM,600
GOTO/0,0,0,0,0,1
GOTO/30,0,0,0,0,1
RAPID
GOTO/30,0,30,0,0,1
RAPID
GOTO/40,0,20,{one}
FEDRAT/MMPM,400
GOTO/40,0,0,{one}
GOTO/40,20,0,{one}
GOTO/30,20,-5,{one}
RAPID
GOTO/30,20,30,{one}
RAPID
GOTO/0,-40,20,{two}
FEDRAT/MMPM,300
GOTO/0,-40,0,{two}
GOTO/20,-40,0,{two}
CYCLE/DRILL,FEDTO,5,MMPM,90,RAPTO,2,RTRCTO,8
GOTO/10,-30,0,{two}
GOTO/20,-30,0,{two}
GOTO/10,-20,3.6397023,{two}
CYCLE/OFF
RAPID
GOTO/10,-20,30,{two}
FINI
"""


def long_indexed_job(points: int = 120) -> str:
    """Two operations at a fixed tilt of ``points`` feed moves each (a zigzag in the plane's
    frame), long enough for a verification in pieces to cut them."""
    out = ["PARTNO LONG INDEXED", "UNITS/MM", "MULTAX/ON", "LOADTL/1", "SPINDL/RPM,8000,CLW"]
    for axis in ((0.5, 0.0, 0.8660254), (0.0, -0.3420201, 0.9396926)):
        i, j, k = axis
        out += ["RAPID", f"GOTO/0,0,40,{i},{j},{k}", "FEDRAT/MMPM,500"]
        for n in range(points):
            x, y = (n % 2) * 20.0 - 10.0, n * 0.25 - 15.0
            out.append(f"GOTO/{x:.4f},{y:.4f},{0.1 * (n % 3):.4f},{i},{j},{k}")
        out += ["RAPID", f"GOTO/0,0,40,{i},{j},{k}"]
    return "\n".join([*out, "FINI", ""])
