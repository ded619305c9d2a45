"""CL jobs shared by the tests of the job around the tool path (tests/test_job.py), of the
process check of ``verify`` (tests/test_verify_process.py) and of the LinuxCNC interpreter
(tests/test_rs274.py)."""

from __future__ import annotations


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
