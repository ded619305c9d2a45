"""Fanuc 30i/31i-B5 (``.nc``): ISO G-code with the Fanuc program frame.

Written::

    %
    O1000 (NAME)
    G21
    G90 G17 G40 G49 G80 G94
    T1 M6
    S12000 M3
    G43.4 H1            (TCP on with the tool's length offset: LOADTL ADJUST, else the tool
                         number; G49 off)
    G0 X10.000 Y-5.000 Z50.000 B0.0000 C90.0000
    G1 Z2.000 F500.
    G28 G91 Z0.         (home: Z first, then X Y, back to G90)
    M30
    %

Every axis value carries a decimal point: without it the control reads least input increments
(``X10`` is 0.010 mm), so the reader rejects axis words without a point.
"""

from __future__ import annotations

import functools
from types import MappingProxyType

from urdfpost.dialects._cycles import iso_lines
from urdfpost.dialects.spec import STANDARD_M_CODES, DialectSpec, MotionLayout, NumberFormat


def _program_name(name: str) -> str:
    """Name inside the ``O1000 (NAME)`` comment."""
    return SPEC.comment_text(name) or "PROGRAM"


G_CODES = MappingProxyType(
    {
        "0": "rapid",
        "1": "linear",
        "2": "arc_cw",
        "3": "arc_ccw",
        "4": "dwell",
        "5.1": "smoothing",
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
        "43.4": "tcp_on",
        "49": "tcp_off",
        "53": "machine",
        "53.1": "tool_axis",
        "68.2": "plane_on",
        **{str(code): "work_offset" for code in range(54, 60)},
        "54.1": "work_offset",
        "61": "noop",
        "64": "noop",
        "69": "plane_off",
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

#: Place among the controls (see :mod:`urdfpost.dialects`).
RANK = 2

SPEC = DialectSpec(
    name="fanuc",
    extensions=(".nc",),
    comment_open="(",
    comment_close=")",
    comment_upper=True,
    comment_replace=MappingProxyType({"(": "[", ")": "]", "%": "", ";": ","}),
    paren_comments=True,
    percent_lines=True,
    program_open=("%", "O{number:04d} ({name})"),
    program_close=("%",),
    setup=("{unit_code}", "G90 G17 G40 G49 G69 G80 G94"),
    finish=("M30",),
    format_name=_program_name,
    program_number_line=True,
    g_codes=G_CODES,
    m_codes=STANDARD_M_CODES,
    tool_change=("T{tool} M6",),
    tool_numbers=(1, 99999999),  # the T word: 8 digits at most (parameter 3032)
    # H: offset memory of 999 registers (system variables #11001-#11999); H0 is no offset
    length_offsets=(1, 999),
    tcp_on=("G43.4 H{offset}",),
    tcp_off=("G49",),
    home=("G28 G91 Z0.", "G28 X0. Y0.", "G90"),
    machine_move="G53 G0 {words}",
    linear_mm=NumberFormat(3, point=True),
    linear_inch=NumberFormat(4, point=True),
    rotary=NumberFormat(4, point=True),
    feed_mm=NumberFormat(1, trim=True, point=True),
    feed_inch=NumberFormat(2, trim=True, point=True),
    require_point=True,
    block_max=99999,
    motion_layout=MotionLayout(),
    cycle_lines=functools.partial(iso_lines, dwell_ms=True),
    dwell=("G4 X{seconds}",),
    dwell_p_ms=True,
    cycle_dwell=frozenset({"drill", "bore"}),
    # AI contour control (AICC II, 30i/31i-B5, with G43.4 TCP): G05.1 Q1 on, Q0 off; its
    # tolerance and precision level are the control's parameters, not program words
    smoothing_on=("G05.1 Q1",),
    smoothing_off=("G05.1 Q0",),
    # G93: F is 1/time in minutes, 0.001 to 9999.999 whatever the units, on every G1 block
    # (Series 16/18 Operator's Manual B-62764EN, "Inverse time feed (G93)")
    inverse_time="G93",
    per_minute="G94",
    inverse_time_feed=NumberFormat(3, trim=True, point=True),
    inverse_time_max=9999.999,
    # G94 with linear and rotary axes: F is the feed along sqrt(dx^2 + ... + dc^2), degrees
    # counted as mm (inch input: as inch) (Power Mate i Operator's Manual B-63174EN, G01)
    axis_feed_rule="combined",
    arc_planes=frozenset({"XY", "ZX", "YZ"}),
    arc_helix=True,
    # G68.2 X Y Z (the plane's zero: the program's) I J K (Euler angles about Z, the turned
    # X, the twice-turned Z), G53.1 (the tool axis along the plane's Z: the rotary axes are
    # there already, the post puts them there before), G69 off; in the plane G43 adds the
    # tool's length along its Z (30i-B Operator's Manual B-64484EN, "Tilted working plane
    # indexing")
    plane_convention="ZXZ",
    plane_on=("G68.2 X0. Y0. Z0. I{a} J{b} K{c}", "G53.1"),
    plane_off=("G69",),
    plane_length_on=("G43 H{offset}",),
    plane_length_off=("G49",),
    cutter_comp=MappingProxyType(
        {"left": "{plane} G41 D{register}", "right": "{plane} G42 D{register}", "off": "G40"}
    ),
)
