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
