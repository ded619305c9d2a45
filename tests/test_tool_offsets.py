"""Tool numbers and tool length offset registers (issue 22).

``LOADTL/3,ADJUST,7`` asks for length offset register 7: Fanuc and LinuxCNC write it as the H
word of the TCP switch (``G43.4 H7``, ``G43 H7``); Heidenhain and Siemens have no such register
(the length is the tool table's, of the tool called), so an ADJUST other than the tool number
is refused there. A tool number or register outside the control's range is refused at the
LOADTL line, before anything is planned.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import pytest
from jobs import TWO_TOOLS

from urdfpost import load_machine
from urdfpost.cli import main
from urdfpost.dialects import DIALECTS
from urdfpost.errors import CLDataError, DialectError
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import post
from urdfpost.program import Program, Tcp, TiltedPlane, ToolChange
from urdfpost.readers import read_cl_text
from urdfpost.toolpath import Toolpath

CONTROLLERS = ("heidenhain", "siemens", "fanuc", "linuxcnc")
WITH_REGISTERS = ("fanuc", "linuxcnc")
WITHOUT_REGISTERS = ("heidenhain", "siemens")
SECOND_TOOL_LINE = 13  # LOADTL/2 of TWO_TOOLS


def two_tools(number: int = 2, adjust: int | None = None, first: int = 1) -> Toolpath:
    """TWO_TOOLS with the second tool ``number`` (and its ``adjust``) set through the
    toolpath API, the first tool ``first``."""
    toolpath = read_cl_text(TWO_TOOLS, source="two.apt")
    events = []
    for e in toolpath.events:
        if e.kind == "tool":
            second = e.line == SECOND_TOOL_LINE
            data = {**e.data, "number": number if second else first}
            if second and adjust is not None:
                data["adjust"] = adjust
            e = replace(e, data=data)
        events.append(e)
    return replace(toolpath, events=tuple(events))


def h_words(text: str) -> list[str]:
    return re.findall(r"(?<![A-Z(])H\d+", text)


@pytest.mark.parametrize("controller", WITH_REGISTERS)
def test_adjust_is_the_h_word_of_the_tcp_switch(controller: str) -> None:
    """Issue 22: ADJUST,7 was dropped and the program used H2; the default stays the tool
    number. The program verifies (its process check compares the registers too)."""
    machine = load_machine("dmu50")
    result = post(two_tools(adjust=7), machine, PostOptions(controller=controller))
    assert h_words(result.text) == ["H1", "H7"]
    read = DIALECTS[controller].read(result.text)
    # (the second tool's cut is at a fixed tilt: in a plane on Fanuc, whose G43 H7 is its length)
    on = [b for b in read.blocks if isinstance(b, Tcp | TiltedPlane) and getattr(b, "on", True)]
    assert [b.offset for b in on if getattr(b, "angles", 0) is not None] == [1, 7]
    plain = post(two_tools(), machine, PostOptions(controller=controller))
    assert h_words(plain.text) == ["H1", "H2"]


@pytest.mark.parametrize("controller", WITHOUT_REGISTERS)
def test_adjust_other_than_the_tool_is_refused_without_registers(controller: str) -> None:
    machine = load_machine("dmu50")
    with pytest.raises(CLDataError) as info:
        post(two_tools(adjust=7), machine, PostOptions(controller=controller))
    assert str(info.value) == (
        f"two.apt:{SECOND_TOOL_LINE}: length offset register 7 (ADJUST) for tool 2: "
        f"{controller} has no length offset register, it takes the length of the tool it "
        "calls from its tool table; expected ADJUST,2 or none"
    )
    # ADJUST naming the tool's own register is what the control does anyway
    same = post(two_tools(adjust=2), machine, PostOptions(controller=controller))
    assert same.text == post(two_tools(), machine, PostOptions(controller=controller)).text


def test_adjust_means_nothing_in_machine_coordinates() -> None:
    """Without TCP the positions hold the tool length: no register is written or checked."""
    result = post(two_tools(adjust=7), load_machine("dmu50"), PostOptions(tcp=False))
    assert h_words(result.text) == []


# the highest tool number of each control, and its register where the tool number is the
# default one (Fanuc: 999 registers, so its highest tool needs an ADJUST)
HIGHEST = {
    "heidenhain": (32767, None),
    "siemens": (32000, None),
    "fanuc": (99999999, 5),
    "linuxcnc": (2147483647, None),
}


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_tool_numbers_within_the_controls_range(controller: str) -> None:
    """Issue 22: tool 1e30 was written as a 31-digit T word. The highest tool of each
    control is written; one more is refused at its LOADTL line, as is tool 0 (no tool)."""
    machine = load_machine("dmu50")
    highest, adjust = HIGHEST[controller]
    spec = DIALECTS[controller].spec
    assert spec.tool_numbers == (1, highest)
    result = post(two_tools(highest, adjust), machine, PostOptions(controller=controller))
    assert re.search(rf"(?<![0-9])(?:T|TOOL CALL ){highest}\b", result.text)
    for number in (highest + 1, 0, int(1e30)):
        with pytest.raises(CLDataError) as info:
            post(two_tools(number, adjust), machine, PostOptions(controller=controller))
        assert str(info.value) == (
            f"two.apt:{SECOND_TOOL_LINE}: tool number {number} is outside the tool numbers of "
            f"{controller} (1 to {highest}); expected a tool the control has"
        )


def test_fanuc_registers_end_at_999() -> None:
    """Tool 1000 with no ADJUST would be H1000, which Fanuc's 999 offsets have not got."""
    machine = load_machine("dmu50")
    with pytest.raises(CLDataError) as info:
        post(two_tools(1000), machine, PostOptions(controller="fanuc"))
    assert str(info.value) == (
        f"two.apt:{SECOND_TOOL_LINE}: length offset register H1000 (the tool number: no ADJUST "
        "given) is outside the registers of fanuc (H1 to H999); expected a tool the control has"
    )
    assert h_words(post(two_tools(1000, 12), machine, PostOptions(controller="fanuc")).text)[
        -1
    ] == ("H12")
    # without TCP no register is written: tool 1000 is fine
    post(two_tools(1000), machine, PostOptions(controller="fanuc", tcp=False))


def test_out_of_range_tool_from_apt_text_exits_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The command line: an input error naming the CL file and the LOADTL line, exit 1."""
    cl = tmp_path / "big.apt"
    cl.write_text(TWO_TOOLS.replace("LOADTL/2", "LOADTL/1e30"))
    out = tmp_path / "big.h"
    code = main(["post", str(cl), "-m", "dmu50", "-c", "heidenhain", "-o", str(out), "-q"])
    assert code == 1
    err = capsys.readouterr().err
    assert f"urdfpost: {cl}:{SECOND_TOOL_LINE}: tool number 1" in err
    assert "is outside the tool numbers of heidenhain (1 to 32767)" in err
    assert not out.exists()


def test_the_writer_refuses_what_the_post_would() -> None:
    """A program built by hand is held to the same ranges by the writer."""
    fanuc, siemens = DIALECTS["fanuc"], DIALECTS["siemens"]
    program = Program("P", ("X",), frozenset(), "mm", True, (ToolChange(1, offset=1000), Tcp(True)))
    with pytest.raises(DialectError, match=r"H1000 \(ADJUST\) is outside the registers of fanuc"):
        fanuc.write(program)
    good = replace(program, blocks=(ToolChange(3, offset=12), Tcp(True)))
    assert "G43.4 H12" in fanuc.write(good)
    with pytest.raises(DialectError, match="tool number 40000 is outside the tool numbers of"):
        siemens.write(replace(program, blocks=(ToolChange(40000),)))


def adjust_from_text() -> bool:
    """Whether the APT reader gives LOADTL's ADJUST (another part of issue 22)."""
    tool = read_cl_text("LOADTL/3,ADJUST,7\nGOTO/0,0,0\n", source="a.apt").events[0]
    return tool.data.get("adjust") == 7


@pytest.mark.parametrize("controller", WITH_REGISTERS)
def test_adjust_from_apt_text(controller: str, tmp_path: Path) -> None:
    if not adjust_from_text():
        pytest.skip("the APT reader does not give LOADTL ADJUST yet")
    cl = tmp_path / "adjust.apt"
    cl.write_text(TWO_TOOLS.replace("LOADTL/2", "LOADTL/2,ADJUST,7"))
    out = tmp_path / f"adjust{DIALECTS[controller].extensions[0]}"
    assert main(["post", str(cl), "-m", "dmu50", "-c", controller, "-o", str(out), "-q"]) == 0
    assert h_words(out.read_text()) == ["H1", "H7"]
