"""Siemens Sinumerik 840D sl (``.mpf`` main program, ``.spf`` subprogram).

Written::

    ; NAME
    G710                 (metric incl. feeds; G700 inch incl. feeds)
    G90 G17 G94
    T1 D1
    M6
    S12000 M3
    TRAORI               (TCP on; TRAFOOF off)
    G0 X10.000 Y-5.000 Z50.000 B0.0000 C90.0000
    G1 Z2.000 F500
    G75 FP=1 Z1=0        (home)
    M30

Home: ``G75 FP=1`` approaches fixed point 1 in machine axes (Z first, then X Y). It keeps
frames and the tool offset (``SUPA G0 Z0 D0`` would cancel D and needs a D1 afterwards;
``G74`` re-references the axes, which is slow and moves them all at once). Fixed point 1 is
machine data (MD30600 FIX_POINT_POS), by convention the tool change / safe position.

The reader also accepts ``N`` numbers, ``X=AC(..)``/``IC(..)``/``DC(..)`` values, ``TRAORI(1)``,
``G70``/``G71`` (inch/mm for lengths only), ``G74`` and ``SUPA`` blocks (read as home).
"""

from __future__ import annotations

from types import MappingProxyType

from urdfpost.dialects._cycles import siemens_lines
from urdfpost.dialects.spec import STANDARD_M_CODES, DialectSpec, MotionLayout, NumberFormat

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
        "40": "comp_off",
        "41": "comp_left",
        "42": "comp_right",
        "710": "mm",
        "700": "inch",
        "71": "mm_geometry",
        "70": "inch_geometry",
        "74": "home",
        "75": "home",
        **{str(code): "work_offset" for code in range(54, 58)},
        "500": "work_offset",
        "60": "noop",
        "64": "noop",
        "90": "absolute",
        "91": "incremental",
        "93": "inverse_time",
        "94": "per_minute",
    }
)

KEYWORDS = MappingProxyType({"TRAORI": "tcp_on", "TRAFOOF": "tcp_off", "SUPA": "machine"})

#: Place among the controls (see :mod:`urdfpost.dialects`).
RANK = 1

SPEC = DialectSpec(
    name="siemens",
    extensions=(".mpf", ".spf"),
    comment_open="; ",
    comment_close="",
    semicolon_comments=True,
    name_comment=True,
    setup=("{unit_code}", "G90 G17 G40 G94", "TRAFOOF", "CYCLE800()"),
    finish=("M30",),
    g_codes=G_CODES,
    m_codes=STANDARD_M_CODES,
    keywords=KEYWORDS,
    assignments=True,
    extra_words=frozenset({"D"}),
    # T1 to T32000 without tool management; D1 is the tool's first edge, whose length the
    # control takes from the tool offset memory of the tool called: no separate register
    tool_change=("T{tool} D1", "M6"),
    tool_numbers=(1, 32000),
    tcp_on=("TRAORI",),
    tcp_off=("TRAFOOF",),
    home=("G75 FP=1 Z1=0", "G75 FP=1 X1=0 Y1=0"),
    machine_move="SUPA G0 {words}",
    work_offsets=4,
    motion_layout=MotionLayout(),
    cycle_lines=siemens_lines,
    dwell=("G4 F{seconds}",),
    cycle_dwell=frozenset({"drill", "deep", "chipbreak", "tap", "bore"}),
    # CYCLE832(contour tolerance, machining type, orientation tolerance in degrees with the
    # _ORI_ types); deselected with the type _OFF (SINUMERIK Operate programming manual,
    # "High Speed Settings - CYCLE832")
    smoothing_on=("CYCLE832({tol},_ORI_FINISH,{angle})",),
    smoothing_off=("CYCLE832(0,_OFF,1)",),
    call_keywords=MappingProxyType({"CYCLE832": "smoothing", "CYCLE800": "plane"}),
    # CYCLE800(_FR, _TC, _ST, _MODE, _X0, _Y0, _Z0, _A, _B, _C, _X1, _Y1, _Z1, _DIR, _FR_I,
    # _DMODE): mode 57, axis by axis in the order X, Y, Z (each about the turned axes); _DIR 0,
    # no swivelling (the rotary axes stand where the program put them); the zero and the
    # zero after it at 0; CYCLE800() deselects the plane (SINUMERIK Operate, "Swivel plane")
    plane_convention="XYZ",
    plane_on=('CYCLE800(0,"",0,57,0,0,0,{a},{b},{c},0,0,0,0,0,1)',),
    plane_off=("CYCLE800()",),
    # a modulo rotary axis is written C=DC(..): the shortest way; a plain value under G90
    # turns without passing 0 (MD30455 $MA_MISC_FUNCTION_MASK bit 2 = 0, the default)
    rollover_value="=DC({value})",
    rollover_direction="direct",
    # G93: "the time required to execute the motion commands in a block", F in 1/min; the
    # feed is reprogrammed after a change of G93/G94/G95 (Programming Manual Fundamentals
    # 6FC5398-2EP40-0BA0, 12/2019, 2.7.1 Feedrate)
    inverse_time="G93",
    per_minute="G94",
    inverse_time_feed=NumberFormat(4, trim=True),
    # G94 without TRAORI: "the feedrate F acts only on path axes" (FGROUP, by default the
    # geometry axes X, Y, Z); the rotary axes follow (same manual, 2.7.1)
    axis_feed_rule="linear-first",
    arc_planes=frozenset({"XY", "ZX", "YZ"}),
    arc_helix=True,
    cutter_comp=MappingProxyType({"left": "{plane} G41", "right": "{plane} G42", "off": "G40"}),
    arc_centre_suffix="=",
)
