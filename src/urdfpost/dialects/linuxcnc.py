"""LinuxCNC RS274NGC (``.ngc``).

Written (no ``%`` delimiters)::

    (NAME)
    G21
    G90 G17 G40 G49 G80 G94
    T1 M6
    S12000 M3
    G43 H1              (TCP on: tool length offset, LOADTL ADJUST else the tool number,
                         then the TCP kinematics)
    M428
    G0 X10.000 Y-5.000 Z50.000 A0.0000 C90.0000
    G1 Z2.000 F500
    M429                (TCP off: identity kinematics, then no length offset)
    G49
    M2

LinuxCNC has no standard TCP G-code. Switchable kinematics configurations switch with
user M-codes remapped to ngc subroutines; in the LinuxCNC 2.9 sims
``configs/sim/axis/vismach/5axis/table-rotary-tilting`` (xyzac-trt, xyzbc-trt) **M428 selects
the XYZAC/XYZBC (TCP) kinematics and M429 the identity kinematics** (see that directory's
``xyzac-trt.txt``/``xyzac-trt.ini``, ``remap_subs/428remap.ngc``, ``429remap.ngc``). Those
kinematics take the tool length from ``motion.tooloffset.z``, i.e. from G43, hence ``G43 H<n>``
before M428. Machines remapped differently need their own ``tcp_on``/``tcp_off`` and
``m_codes`` entries.

Comments are ``(...)``; text that LinuxCNC would act on (``(MSG,``, ``(DEBUG,``, ``(PRINT,``,
``(LOG...``, ``(PROBE...``, ``(ABORT,``) has its comma replaced so it stays a plain comment.
The reader also accepts ``;`` comments, ``%`` lines and lower case.
"""

from __future__ import annotations

import functools
import re
from types import MappingProxyType

from urdfpost.dialects._cycles import iso_lines
from urdfpost.dialects.spec import STANDARD_M_CODES, DialectSpec, MotionLayout, NumberFormat

_ACTIVE_COMMENT = re.compile(
    r"^(\s*(?:MSG|DEBUG|PRINT|LOG|LOGOPEN|LOGAPPEND|LOGCLOSE|PROBEOPEN|PROBECLOSE|ABORT))\s*,",
    re.IGNORECASE,
)


def _passive_comment(text: str) -> str:
    """Keep LinuxCNC from acting on a comment (``MSG, x`` -> ``MSG: x``)."""
    return _ACTIVE_COMMENT.sub(r"\1:", text)


G_CODES = MappingProxyType(
    {
        "0": "rapid",
        "1": "linear",
        "2": "arc_cw",
        "3": "arc_ccw",
        "4": "dwell",
        "17": "plane_xy",
        "18": "plane_zx",
        "19": "plane_yz",
        "21": "mm",
        "20": "inch",
        "28": "home",
        "40": "comp_off",
        "41": "comp_left",
        "42": "comp_right",
        "43": "length_on",
        "49": "noop",
        "53": "machine",
        **{str(code): "work_offset" for code in range(54, 60)},
        "61": "noop",
        "64": "blend",
        "80": "cycle_off",
        **{code: "cycle" for code in ("73", "81", "82", "83", "84", "85", "89")},
        "98": "cycle_initial",
        "99": "cycle_r",
        "90": "absolute",
        "91": "incremental",
        "93": "inverse_time",
        "94": "per_minute",
    }
)

M_CODES = MappingProxyType({**STANDARD_M_CODES, 428: "tcp_on", 429: "tcp_off"})

#: Place among the controls (see :mod:`urdfpost.dialects`).
RANK = 3

SPEC = DialectSpec(
    name="linuxcnc",
    extensions=(".ngc",),
    comment_open="(",
    comment_close=")",
    comment_replace=MappingProxyType({"(": "[", ")": "]"}),
    comment_filter=_passive_comment,
    paren_comments=True,
    semicolon_comments=True,
    percent_lines=True,
    name_comment=True,
    setup=("{unit_code}", "G90 G17 G40 G49 G80 G94", "M429"),
    finish=("M2",),
    g_codes=G_CODES,
    m_codes=M_CODES,
    tool_change=("T{tool} M6",),
    # tool numbers and G43 H (a tool table entry): the interpreter's int; rs274 refuses
    # T2147483648 ("Negative tool id"), T0 is the empty spindle
    tool_numbers=(1, 2147483647),
    length_offsets=(1, 2147483647),
    tcp_on=("G43 H{offset}", "M428"),
    tcp_off=("M429", "G49"),
    home=("G28 G91 Z0", "G28 X0 Y0", "G90"),
    block_max=99999,
    motion_layout=MotionLayout(),
    cycle_lines=functools.partial(iso_lines, dwell_ms=False),
    dwell=("G4 P{seconds}",),
    dwell_p_ms=False,
    cycle_dwell=frozenset({"drill", "bore"}),
    # G64 P<path tolerance> Q<naive CAM tolerance>; G64 without P: blending without a
    # tolerance, the interpreter's own mode (LinuxCNC G-code reference, G64)
    smoothing_on=("G64 P{tol} Q{tol}",),
    smoothing_off=("G64",),
    # [AXIS_C] WRAPPED_ROTARY = 1: the sign of an absolute value is the direction of the
    # turn, its magnitude (less than 360) the position (interp_convert.cc unwrap_rotary)
    rollover_direction="sign",
    # G93: the move takes 1/F minutes; an F word on every G1 line (LinuxCNC G-code manual,
    # G93 G94 G95; rs274 refuses a G1 without F in G93)
    inverse_time="G93",
    per_minute="G94",
    inverse_time_feed=NumberFormat(4, trim=True),
    # G94: F along X, Y, Z as if the rotary axes did not move; degrees per minute along the
    # rotary axes when X, Y, Z do not move (RS274NGC 3, NIST IR 6556, 2.1.2.5 "Feed Rate")
    axis_feed_rule="linear-first",
    arc_planes=frozenset({"XY", "ZX", "YZ"}),
    arc_helix=True,
    cutter_comp=MappingProxyType(
        {"left": "{plane} G41 D{register}", "right": "{plane} G42 D{register}", "off": "G40"}
    ),
)
