"""Tests of the streaming CL reader (urdfpost.readers.read_cl_chunks).

Every case compares the pieces with what :func:`read_cl` returns for the same file and
arguments: the pieces must be consecutive slices of it, bit for bit, with its events,
warnings, units and errors.
"""

from __future__ import annotations

import importlib.util
import itertools
import math
import re
import tracemalloc
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_cl
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import urdfpost.readers.apt as apt_module
from urdfpost.errors import CLDataError
from urdfpost.readers import FORMATS, detect_file_format, detect_format, read_cl, read_cl_chunks
from urdfpost.readers._stream import text_pieces
from urdfpost.toolpath import Toolpath
from urdfpost.units import MM_PER_INCH

DATA = Path(__file__).parent / "data" / "cl"
DATA_FILES = sorted(p.name for p in DATA.iterdir() if p.is_file())
SHARED_FILES = ["nx_variable_axis_ballmill_inch.cls", "nx_project2_15ops_inch.cls"]
FIELDS = ("tip", "axis", "feed", "motion", "line")


# -- the contract, checked against read_cl ----------------------------------------------------


def outcome(read: Callable[[], object]) -> object:
    """What ``read()`` returns, or the CL data error it raises as comparable values."""
    try:
        return read()
    except CLDataError as exc:
        return ("CLDataError", exc.path, exc.line, str(exc))


def event_keys(toolpath: Toolpath, offset: int = 0) -> list[tuple]:
    """Events as comparable values (repr of the data: a NaN spindle speed equals itself)."""
    return [(e.index + offset, e.kind, e.line, repr(e.data)) for e in toolpath.events]


def assert_pieces_of(pieces: Sequence[Toolpath], whole: Toolpath, max_points: int) -> None:
    """``pieces`` are consecutive slices of ``whole`` as read_cl_chunks promises."""
    sizes = [len(p) for p in pieces]
    if len(whole) == 0:
        assert sizes == [0]
    else:
        assert all(1 <= n <= max_points for n in sizes), sizes
        assert all(n == max_points for n in sizes[:-1]), sizes
    assert sum(sizes) == len(whole)
    for name in FIELDS:
        joined = np.concatenate([getattr(p, name) for p in pieces])
        expected = getattr(whole, name)
        assert joined.dtype == expected.dtype and joined.shape == expected.shape, name
        assert joined.tobytes() == expected.tobytes(), name  # bit for bit: NaN, -0.0 too
    events, offset = [], 0
    for k, piece in enumerate(pieces):
        last = k == len(pieces) - 1
        for event in piece.events:
            assert 0 <= event.index < len(piece) or (last and event.index == len(piece))
        events += event_keys(piece, offset)
        offset += len(piece)
    assert events == event_keys(whole)
    assert [w for p in pieces for w in p.warnings] == list(whole.warnings)
    assert {(p.units, p.source) for p in pieces} == {(whole.units, whole.source)}
    flags = [p.multiaxis for p in pieces]
    assert flags[-1] == whole.multiaxis
    assert flags == sorted(flags)  # once a record carried a tool axis, every later piece


def check_file(path: Path, max_points: int, text_piece: int, **kwargs) -> list[Toolpath] | None:
    """Compare read_cl_chunks with read_cl; the pieces (None when both raise the same)."""
    whole = outcome(lambda: read_cl(path, **kwargs))
    pieces = outcome(
        lambda: list(read_cl_chunks(path, max_points=max_points, _text_piece=text_piece, **kwargs))
    )
    if isinstance(whole, tuple):
        assert pieces == whole
        return None
    assert isinstance(pieces, list), pieces
    assert_pieces_of(pieces, whole, max_points)
    return pieces


# -- an independent view of the records, for the multi-axis flag of each piece ----------------


def simple_records(text: str) -> list[tuple[int, str, list[str] | None]]:
    """(line, word, args) of the logical records up to FINI: ``$`` continues a record, ``$$``
    starts a comment (whole-line comments are left out); free text (PPRINT, PARTNO, INSERT) is
    one line, ``$`` and ``$$`` in it are text; a motion record never continues another."""
    records, pending, start = [], None, 0
    for number, raw in enumerate(re.split(r"\r\n|\r|\n", text), start=1):
        stripped = raw.strip()
        if not stripped or (pending is None and stripped.startswith("$$")):
            continue
        if pending is None and re.match(r"(PPRINT|PARTNO|INSERT)(?![A-Za-z0-9_])", stripped, re.I):
            records.append((number, stripped[:6].upper().rstrip(), None))
            continue
        if pending is not None and re.match(r"(GOTO|FROM|GODLTA|CIRCLE)[ \t]*/", stripped, re.I):
            raise ValueError(f"line {number}: a motion record continues the record at {start}")
        code = stripped.partition("$$")[0].rstrip()
        continued = code.endswith("$")
        code = code[:-1] if continued else code
        pending, start = (code, number) if pending is None else (pending + code, start)
        if continued:
            continue
        word, slash, rest = pending.partition("/")
        args = [a.strip() for a in rest.split(",")] if slash else None
        records.append((start, " ".join(word.upper().split()), args))
        pending = None
        if records[-1][1] == "FINI":
            break
    return records


def apt_axis_lines(text: str) -> tuple[float, dict[int, int]]:
    """The line of the first record that carries a tool axis (inf for none), and the line of
    the GOTO that ends each CIRCLE (by the CIRCLE's line)."""
    first = math.inf
    arc_end: dict[int, int] = {}
    circle = None
    for line, word, args in simple_records(text):
        if word in ("GOTO", "FROM") and args is not None and len(args) == 6:
            first = min(first, line)
        if word == "MULTAX" and (args is None or [a.upper() for a in args] == ["ON"]):
            first = min(first, line)
        if word == "CIRCLE":
            circle = line
        elif word == "GOTO" and circle is not None:
            arc_end[circle] = line
            circle = None
    return first, arc_end


def plain_axis_line(text: str) -> float:
    """The line of the first point with a tool axis in a plain point list (inf for none)."""
    for number, raw in enumerate(re.split(r"\r\n|\r|\n", text), start=1):
        code = re.split(r"[#;]", raw)[0].strip()
        if code and len(re.split(r"\s*,\s*|\s+", code)) == 6:
            return number
    return math.inf


def assert_multiaxis_flags(
    pieces: Sequence[Toolpath], whole: Toolpath, first: float, arc_end: dict[int, int]
) -> None:
    """Each piece is multi-axis when a point of it or before it was made by a record at or
    after the first one with a tool axis (an arc's last point is made by its end GOTO)."""
    made_by = whole.line.astype(float)
    for j in range(len(whole)):
        line = int(whole.line[j])
        if line in arc_end and (j + 1 == len(whole) or whole.line[j + 1] != line):
            made_by[j] = arc_end[line]
    end = 0
    for piece in pieces[:-1]:
        end += len(piece)
        assert piece.multiaxis == bool((made_by[:end] >= first).any()), end
    assert pieces[-1].multiaxis == whole.multiaxis


# -- the readers --------------------------------------------------------------------------------


def test_every_format_streams():
    # every format that can be detected has a data file, so test_data_files streams it
    detected = {detect_format((DATA / name).read_text()) for name in DATA_FILES}
    assert {n for n, f in FORMATS.items() if f.detect or f.fallback} <= detected
    assert all(callable(f.read_stream) for f in FORMATS.values())


@pytest.mark.parametrize(
    "text",
    ["1 2 3\rGOTO/1,2,3\r", "1 2 3\r$$ x\n", "1 2 3\n4 5 6\r\n  goto / 1, 2, 3\n", "1 2 3\n" * 40],
)
@pytest.mark.parametrize("text_piece", [1, 3, 7, 1 << 23])
def test_file_format_is_the_text_format(tmp_path, text, text_piece):
    path = tmp_path / "cl.txt"
    path.write_bytes(text.encode())
    assert detect_file_format(str(path), text_piece) == detect_format(text)


def test_data_files_are_there():
    assert {"creo_split.ncl", "catia_style.aptsource", "plain_points.txt"} <= set(DATA_FILES)


@pytest.mark.parametrize("name", DATA_FILES)
@pytest.mark.parametrize("max_points", [1, 2, 3, 7, 1000])
@pytest.mark.parametrize("text_piece", [1, 7, 64, 1 << 23])
def test_data_files(name, max_points, text_piece):
    path = DATA / name
    pieces = check_file(path, max_points, text_piece)
    assert pieces is not None
    whole = read_cl(path)
    if name.endswith(".txt"):
        assert_multiaxis_flags(pieces, whole, plain_axis_line(path.read_text()), {})
    else:
        assert_multiaxis_flags(pieces, whole, *apt_axis_lines(path.read_text()))


@pytest.mark.parametrize(
    ("name", "max_points", "text_piece"),
    [
        ("nx_variable_axis_ballmill_inch.cls", 1, 1),
        ("nx_variable_axis_ballmill_inch.cls", 2, 7),
        ("nx_variable_axis_ballmill_inch.cls", 3, 64),
        ("nx_variable_axis_ballmill_inch.cls", 7, 1 << 23),
        ("nx_variable_axis_ballmill_inch.cls", 347, 100),
        ("nx_project2_15ops_inch.cls", 3, 4096),
        ("nx_project2_15ops_inch.cls", 7, 64),
        ("nx_project2_15ops_inch.cls", 333, 997),
        ("nx_project2_15ops_inch.cls", 5000, 1 << 23),
        ("nx_project2_15ops_inch.cls", 10**6, 1 << 14),
    ],
)
def test_shared_files(name, max_points, text_piece):
    path = shared_cl(name)
    pieces = check_file(path, max_points, text_piece)
    assert pieces is not None
    assert_multiaxis_flags(pieces, read_cl(path), *apt_axis_lines(path.read_text()))


def test_shared_file_other_arguments():
    path = shared_cl("nx_project2_15ops_inch.cls")
    pieces = check_file(path, 1000, 1 << 12, format="APT", units="mm", chord_tolerance=0.02)
    # units= win over the file's FEDRAT/IPM (line 21), with one warning, in the first piece
    assert pieces is not None and pieces[0].units == "mm"
    assert pieces[0].warnings == (
        f"{path}:21: CL file says inch at line 21; read as mm (--cl-units)",
        f"{path}:22: CIRCLE sense inferred, not declared: arcs turn clockwise about the circle "
        "axis, the NX CLSF convention (an NX listing line at line 2); each arc is checked "
        "against the feed moves before and after it",
    )
    assert [w for p in pieces[1:] for w in p.warnings] == []


# -- generated text -----------------------------------------------------------------------------

_number = st.one_of(
    st.floats(-50, 50, allow_nan=False).map(lambda v: f"{v:.4f}"),
    st.integers(-20, 20).map(str),
    st.sampled_from(["-0", "+.5", "5.", "1E1", "-0.0", " 2 ", "0"]),
)
_axis = st.sampled_from(
    ["0,0,1", "0.6,0,0.8", "0.000000,0.707107,0.707107", "-0,-0,-1", "0,0,2", "1,0,0"]
)
_goto = st.one_of(
    st.lists(_number, min_size=3, max_size=3).map(lambda v: "GOTO/" + ",".join(v)),
    st.tuples(st.lists(_number, min_size=3, max_size=3), _axis).map(
        lambda v: "GOTO/" + ",".join(v[0]) + "," + v[1]
    ),
)


@st.composite
def _continued(draw: st.DrawFn) -> list[str]:
    """A GOTO record cut over several lines with '$' (in Creo's ``GOTO / x, y`` style too)."""
    values = draw(st.lists(_number, min_size=3, max_size=3)) + draw(
        st.sampled_from([[], ["0", "0.6", "0.8"]])
    )
    cuts = draw(st.sets(st.integers(0, len(values) - 2), min_size=1))
    lines, current = [], draw(st.sampled_from(["GOTO/", "GOTO / ", "goto/"]))
    for k, value in enumerate(values):
        current += value
        if k == len(values) - 1:
            break
        current += ","
        if k in cuts:
            lines.append(current + draw(st.sampled_from(["$", " $", "$ $$ note"])))
            current = draw(st.sampled_from(["", "   "]))
    return [*lines, current]


@st.composite
def _arc(draw: st.DrawFn) -> list[str]:
    """CIRCLE and the GOTO that ends it (a point on the circle, sometimes with a tool axis)."""
    t = draw(st.floats(0, 2 * math.pi))
    z = draw(st.sampled_from(["0", "0.5", "-1"]))
    times = draw(st.sampled_from(["", ",0.05,0.5,1,TIMES,2"]))
    end = f"GOTO/{10 * math.cos(t):.4f},{10 * math.sin(t):.4f},{z}"
    end += draw(st.sampled_from(["", ",0,0,1", ",0,0.6,0.8"]))
    between = draw(st.sampled_from([[], ["PAINT/COLOR,3"], ["$$ on the arc"]]))
    return [f"CIRCLE/0,0,0,0,0,1,10{times}", *between, end]


_other = st.sampled_from(
    [
        "RAPID",
        "FEDRAT/200",
        "FEDRAT/IPM,5",
        "FEDRAT/MMPR,0.1",
        "SPINDL/1000,CLW",
        "SPINDL/ON",
        "SPINDL/OFF",
        "COOLNT/MIST",
        "$$ a comment, café",
        "PPRINT hello world",
        "INSERT G90",
        "",
        "   ",
        "UNITS/INCHES",
        "UNITS/MM",
        "MSYS/1,2,3,0,1,0,-1,0,0",
        "MULTAX",
        "MULTAX/ON",
        "MULTAX/OFF",
        "LOADTL/2",
        "CUTTER/6,1",
        "TOOL PATH/OP1,TOOL,T1",
        "PAINT/COLOR,3",
        "FOO/1,2",
        "  GOTO/1,2,3",
        "FROM/0,0,50",
        "GODLTA/0,0,5",
        "GODLTA/-2",
        "LOADTL/3,ADJUST,7",
        "GOHOME",
        "Tool Path Listing has 99 lines.",
    ]
)
_bad = st.sampled_from(
    [
        "GOTO/1,2",
        "GOTO/1,x,3",
        "GOTO/1,2,3,0,0,0",
        "CIRCLE/0,0,0,0,0,1,-1",
        "GOTO/1,2,IPM",  # a feed unit in a GOTO line: the file's units, then an error
        "GOTO/1,2,3,0,0,mmpr",
    ]
)
_record = st.one_of(
    _goto.map(lambda x: [x]),
    st.lists(_goto, min_size=3, max_size=8),  # a run read in bulk (BULK_MIN_RECORDS is 3 here)
    _other.map(lambda x: [x]),
    _continued(),
    _arc(),
    # a line ending with "$" before a GOTO run: text in free-text records, else an error
    st.tuples(st.sampled_from(["PPRINT note $", "FEDRAT/ $", "INSERT X$"]), st.lists(_goto)).map(
        lambda v: [v[0], *v[1]]
    ),
)


@st.composite
def apt_texts(draw: st.DrawFn) -> str:
    records = draw(st.lists(_record, max_size=14))
    if draw(st.integers(0, 9)) == 0:  # now and then a bad record, or FINI and lines after it
        records.insert(draw(st.integers(0, len(records))), [draw(_bad)])
    if draw(st.integers(0, 5)) == 0:
        records.insert(draw(st.integers(0, len(records))), ["FINI"])
    if draw(st.integers(0, 20)) == 0:
        records.append(["GOTO/1,2,$"])  # a record left open at the end of the file
    newline = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    text = newline.join(line for record in records for line in record)
    return text + draw(st.sampled_from([newline, ""]))


_text_pieces = st.sampled_from([1, 2, 3, 5, 7, 16, 64, 4096])


def whole_file_facts(text: str, source: str) -> object:
    """Units declared and NX dialect, as read_apt_text finds them in the whole text."""

    def facts() -> tuple[tuple[str, int] | None, tuple[int, str] | None]:
        scan = apt_module.scan_text(text, source)
        nx = apt_module.nx_evidence(scan.records, scan.first_listing)
        return apt_module._file_units(scan.records), nx

    return outcome(facts)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(apt_texts(), st.integers(1, 12), _text_pieces, st.sampled_from([40, 1 << 18]))
def test_generated_apt(tmp_path_factory, text, max_points, text_piece, bulk_piece):
    path = tmp_path_factory.mktemp("apt") / "gen.apt"
    path.write_bytes(text.encode())
    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 3)
        monkeypatch.setattr(apt_module, "_STREAM_PART", bulk_piece)
        # the quick pre-scan finds what the whole-file scan finds (or its error)
        facts = outcome(lambda: apt_module._apt_facts(str(path), text_piece)[:2])
        assert facts == whole_file_facts(text, str(path))
        # the streaming reader's pass stops at the part with the first UNITS record: the
        # same units, and the NX evidence where it says it is complete (else none yet)
        part = outcome(lambda: apt_module._apt_facts(str(path), text_piece, whole=False))
        if isinstance(part, tuple) and len(part) == 3 and isinstance(part[2], bool):
            if not isinstance(facts[0], str):  # (facts is no error)
                assert part[0] == facts[0]
                assert part[1] == (facts[1] if part[2] else None)
        else:  # an error it meets before it stops is the whole pass's
            assert part == facts
        pieces = check_file(path, max_points, text_piece, format="apt", chord_tolerance=0.05)
        if pieces is not None:
            whole = read_cl(path, format="apt", chord_tolerance=0.05)
            assert_multiaxis_flags(pieces, whole, *apt_axis_lines(text))


@pytest.mark.parametrize(
    ("text", "facts"),
    [
        # (units, line that declares them), where the file shows NX CLSF
        ("GOTO/1,2,3\n" * 5 + "GOTO/1,2,IPM\n" + "GOTO/1,2,3\n" * 5, (("inch", 6), None)),
        ("goto / 1, 2, 3\n  GOTO/1,2,3,0,0,mmpr\n", (("mm", 2), None)),
        ("FEDRAT/IPM,1\nGOTO/1,2,3\nUNITS/MM\n", (("mm", 3), None)),
        ("FEDRAT/$\nIPM,5\nGOTO/1,2,3\n", (("inch", 1), None)),
        ("PPRINT x $\n" + "GOTO/1,2,3\n" * 4, (None, None)),
        ("PPRINT x $\nGOTO/1,2,3\nUNITS/INCHES\n", (("inch", 3), None)),
        ("GOTO/1,2,3\nTLDATA/MILL,1\n", (None, (2, "the NX record TLDATA"))),
        ("GOTO/1,2,3\nMSYS/0,0,0,1,0,0,0,1,0\n", (None, (2, "the NX record MSYS"))),
        ("GOTO/1,2,3\nTool Path Listing has 3 lines.\n", (None, (2, "an NX listing line"))),
        (
            "Tool Path Listing has 3 lines.\n" + "GOTO/1,2,3\n" * 40 + "PAINT/X\n",
            (None, (1, "an NX listing line")),
        ),
        (
            "GOTO/1,2,3\n" * 40 + "PAINT/X\nTool Path Listing has 3 lines.\n",
            (None, (41, "the NX record PAINT")),
        ),
        ("GOTO/1,2,3\nFINI\nUNITS/INCHES\nPAINT/X\n", (None, None)),
        ("GOTO/1,2,3\n" * 3 + "GOTO/1,2,$\n", ("CLDataError", 4)),
    ],
)
@pytest.mark.parametrize("text_piece", [1, 5, 16, 1 << 23])
def test_prescan_finds_what_the_whole_scan_finds(tmp_path, text, facts, text_piece):
    path = tmp_path / "facts.apt"
    path.write_text(text)
    found = outcome(lambda: apt_module._apt_facts(str(path), text_piece)[:2])
    assert found == whole_file_facts(text, str(path))
    if facts[0] == "CLDataError":
        assert (found[0], found[2]) == facts
    else:
        assert found == facts


_plain_line = st.one_of(
    st.lists(_number, min_size=3, max_size=3).map(" ".join),
    st.tuples(st.lists(_number, min_size=3, max_size=3), _axis).map(
        lambda v: ", ".join(v[0]) + ", " + v[1]
    ),
    st.sampled_from(["", "# comment", "1 2 3 ; tilt", "; only", "  ", "1 2 3 0 0 1 # c"]),
)


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(_plain_line, max_size=20),
    st.sampled_from(["\n", "\r\n", "\r"]),
    st.booleans(),
    st.integers(1, 6),
    _text_pieces,
    st.booleans(),
)
def test_generated_plain(
    tmp_path_factory, lines, newline, final, max_points, text_piece, with_error
):
    if with_error and lines:
        lines[len(lines) // 2] = "1 2"
    text = newline.join(lines) + (newline if final else "")
    path = tmp_path_factory.mktemp("plain") / "gen.txt"
    path.write_bytes(text.encode())
    pieces = check_file(path, max_points, text_piece, format="plain", units="inch")
    if pieces is not None:
        first = plain_axis_line(text)
        assert_multiaxis_flags(pieces, read_cl(path, format="plain"), first, {})


# -- text pieces that cut through records -------------------------------------------------------

STRADDLING = (
    "PARTNO STRADDLE\r\n"
    "$$ a comment that is longer than a text piece\r\n"
    "FEDRAT/ $\r\n"
    "   250 $$ continued\r\n"
    "GOTO/10.0000,0.0000,0.5000\r\n"
    "GOTO / 10.0000, 0.0000, $\r\n"
    "       1.0000, 0.0, 0.6, 0.8\r\n"
    "CIRCLE/0,0,0,0,0,1,10,$\r\n"
    "0.05,0.5,1\r\n"
    "PAINT/COLOR,3\r\n"
    "GOTO/0.0000,10.0000,1.0000\r\n"
    "FOO/unknown\r\n"
    "UNITS/INCHES\r\n"
    "GOTO/1,1,1\r\n"
    "FINI\r\n"
    "junk after FINI\r\n"
    "\r\n"
    "more junk"
)


@pytest.mark.parametrize("max_points", [1, 3, 1000])
def test_text_piece_boundaries_everywhere(tmp_path, max_points):
    path = tmp_path / "straddle.apt"
    path.write_bytes(STRADDLING.encode())
    whole = read_cl(path)
    # the CIRCLE sense, an unknown record, junk after FINI
    assert whole.units == "inch" and len(whole.warnings) == 3
    assert whole.warnings[-1].endswith(":16: 2 non-blank line(s) after FINI ignored")
    for text_piece in [*range(1, 40), 64, 1 << 23]:
        check_file(path, max_points, text_piece)


def test_units_from_the_end_of_the_file(tmp_path):
    path = tmp_path / "late_units.apt"
    path.write_text("".join(f"GOTO/{k},0,0\n" for k in range(50)) + "UNITS/INCHES\n")
    pieces = check_file(path, 7, 16)
    assert pieces is not None and len(pieces) == 8
    assert pieces[0].units == "inch"
    assert pieces[0].tip[1, 0] == MM_PER_INCH


def test_nx_record_at_the_end_turns_every_arc(tmp_path):
    text = "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n" + "GOTO/0,10,1\n" * 5
    plain, nx = tmp_path / "apt.apt", tmp_path / "nx.apt"
    plain.write_text(text)
    nx.write_text(text + "PAINT/COLOR,3\n")
    apt_pieces = check_file(plain, 2, 8)
    nx_pieces = check_file(nx, 2, 8)
    assert apt_pieces is not None and nx_pieces is not None
    # the same arc the other way round: the first piece already knows
    assert not np.allclose(apt_pieces[0].tip, nx_pieces[0].tip)


def test_no_motion_is_one_empty_piece(tmp_path):
    empty, comments = tmp_path / "empty.apt", tmp_path / "comments.apt"
    empty.write_text("")
    comments.write_text("$$ one\nPARTNO X\n$$ two\nFINI\n")
    assert [len(p) for p in read_cl_chunks(empty, max_points=3)] == [0]
    pieces = check_file(comments, 3, 4)
    assert pieces is not None and [len(p) for p in pieces] == [0]
    assert [e.index for e in pieces[0].events] == [0, 0, 0]


def test_events_and_warnings_go_with_their_points(tmp_path):
    path = tmp_path / "events.apt"
    path.write_text(
        "$$ start\nGOTO/0,0,0\nGOTO/1,0,0\nFOO/1\nGOTO/2,0,0\nGOTO/3,0,0\nBAR/2\n$$ end\n"
    )
    pieces = check_file(path, 2, 1 << 23)
    assert pieces is not None
    # a warning goes with its record's event, whenever the piece is handed out
    assert [(len(p), event_keys(p), [w.split(":")[1] for w in p.warnings]) for p in pieces] == [
        (2, [(0, "comment", 1, "{'text': 'start'}")], []),
        (
            2,
            [
                (0, "unknown", 4, "{'text': 'FOO/1'}"),
                (2, "unknown", 7, "{'text': 'BAR/2'}"),
                (2, "comment", 8, "{'text': 'end'}"),
            ],
            ["4", "7"],
        ),
    ]


@pytest.mark.parametrize(
    ("text", "flags"),
    [
        ("GOTO/0,0,0\nGOTO/1,0,0\nMULTAX\nGOTO/2,0,0\n", [False, False, True]),
        ("GOTO/0,0,0\nGOTO/1,0,0\nMULTAX/ON\n", [False, True]),
        ("GOTO/0,0,0\nGOTO/1,0,0,0,0.6,0.8\nGOTO/2,0,0\n", [False, True, True]),
        ("GOTO/0,0,0\nGOTO/1,0,0\n", [False, False]),
    ],
)
def test_multiaxis_of_each_piece(tmp_path, text, flags):
    path = tmp_path / "axis.apt"
    path.write_text(text)
    assert [p.multiaxis for p in read_cl_chunks(path, max_points=1)] == flags


def test_multiaxis_of_an_arc_is_set_by_its_last_point(tmp_path):
    path = tmp_path / "arc.apt"
    path.write_text("GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0,0,0.6,0.8\nGOTO/0,9,0\n")
    pieces = check_file(path, 1, 1 << 23)
    assert pieces is not None and len(pieces) > 4
    assert [p.multiaxis for p in pieces] == [False] * (len(pieces) - 2) + [True, True]


# -- errors -------------------------------------------------------------------------------------


def test_bad_record_in_a_later_piece(tmp_path):
    path = tmp_path / "bad.apt"
    path.write_text("".join(f"GOTO/{k},0,0\n" for k in range(100)) + "GOTO/1,2\nGOTO/3,4,5\n")
    with pytest.raises(CLDataError) as whole:
        read_cl(path)
    assert whole.value.line == 101
    pieces = read_cl_chunks(path, max_points=10, _text_piece=256)
    got = []
    with pytest.raises(CLDataError) as streamed:
        got.extend(pieces)
    assert str(streamed.value) == str(whole.value)
    assert (streamed.value.path, streamed.value.line) == (str(path), 101)
    assert len(got) >= 5  # the pieces before the bad record came first
    assert all(len(p) == 10 for p in got)


@pytest.mark.parametrize(
    ("text", "line"),
    [
        # a record left open by the end of the file is found before an earlier bad record
        ("GOTO/0,0,0\nGOTO/1,x,0\nGOTO/2,0,$", 3),
        ("GOTO/0,0,0\nCIRCLE/0,0,0,0,0,1,10\n", 2),  # no GOTO after CIRCLE
        ("GOTO/0,0,0\nCIRCLE/0,0,0,0,0,1,10\nFINI\n", 2),
        ("GOTO/0,0,0\n" * 40 + "GOTO/0,0,0,0,0,0\n", 41),
    ],
)
def test_errors_are_read_cl_errors(tmp_path, text, line):
    path = tmp_path / "bad.apt"
    path.write_text(text)
    with pytest.raises(CLDataError) as whole:
        read_cl(path)
    assert whole.value.line == line
    for max_points, text_piece in [(1, 1), (3, 7), (1000, 1 << 23)]:
        assert check_file(path, max_points, text_piece) is None


def test_open_record_at_the_end_raises_before_the_first_piece(tmp_path):
    path = tmp_path / "open.apt"
    path.write_text("GOTO/0,0,0\n" * 50 + "GOTO/1,2,$\n")
    pieces = read_cl_chunks(path, max_points=1, _text_piece=64)
    with pytest.raises(CLDataError, match=r"open\.apt:51: expected the continuation"):
        next(pieces)


def test_missing_file(tmp_path):
    missing = tmp_path / "missing.cls"
    assert check_file(missing, 5, 64) is None
    with pytest.raises(CLDataError, match=r"missing\.cls: cannot read: "):
        next(read_cl_chunks(missing, max_points=5))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"max_points": 0},
        {"max_points": -3},
        {"max_points": 2.5},
        {"max_points": 5, "format": "gcode"},
        {"max_points": 5, "units": "furlong"},
        {"max_points": 5, "format": "apt", "chord_tolerance": 0.0},
        {"max_points": 5, "_text_piece": 0},
    ],
)
def test_bad_arguments_before_reading(tmp_path, kwargs):
    # a missing file: a ValueError shows that the arguments were checked before reading
    with pytest.raises(ValueError):
        read_cl_chunks(tmp_path / "missing.apt", **kwargs)


def test_chord_tolerance_of_a_detected_format(tmp_path):
    apt_file, plain_file = tmp_path / "a.apt", tmp_path / "p.txt"
    apt_file.write_text("GOTO/1,2,3\n")
    plain_file.write_text("1 2 3\n")
    pieces = read_cl_chunks(apt_file, max_points=5, chord_tolerance=-1.0)
    with pytest.raises(ValueError, match="chord_tolerance"):
        next(pieces)
    assert check_file(plain_file, 5, 3, chord_tolerance=-1.0) is not None  # as read_cl


# -- reading the text ---------------------------------------------------------------------------

AWKWARD = (
    b"$$ caf\xc3\xa9 \xe2\x9c\x93 \xff\xfe bad \xe2\x9c\r\n"
    b"GOTO/1,2,3\rGOTO/4,5,6\n\r\nPPRINT \xf0\x9f\x94\xa7 tool\r"
    b"\r\n\n\rGOTO/7,8,9 $$ \xc3"
)


@pytest.mark.parametrize("size", [1, 2, 3, 5, 8, 13, 1 << 20])
def test_text_pieces(tmp_path, size):
    path = tmp_path / "awkward.apt"
    path.write_bytes(AWKWARD)
    with open(path, encoding="utf-8", errors="replace", newline="") as handle:
        text = handle.read()
    pieces = list(text_pieces(str(path), size))
    assert "".join(pieces) == text
    assert all(p.endswith(("\n", "\r")) for p in pieces[:-1])
    assert not any(a.endswith("\r") and b.startswith("\n") for a, b in itertools.pairwise(pieces))
    if size == 1:
        assert len(pieces) == len(re.findall(r"\r\n|\r|\n", text)) + 1  # one line each
    check_file(path, 2, size)


def test_format_detected_on_the_whole_file(tmp_path):
    late, cr_only = tmp_path / "late.cl", tmp_path / "cr.cl"
    late.write_text("1 2 3\n" * 30 + "$$ an APT comment\n")
    cr_only.write_text("1 2 3\rGOTO/1,2,3\r")  # a CR starts a line: APT, as the reader splits
    # APT (a $$ comment), so 30 unknown records and no motion: refused, whole and in pieces
    assert check_file(late, 4, 16) is None
    with pytest.raises(CLDataError, match=r"late.cl:1: not a CL file: no motion record, and 30 of"):
        read_cl(late)
    for text_piece in (1, 6, 7, 64):  # (one GOTO, line 1 an unknown record: the same in pieces)
        (piece,) = check_file(cr_only, 4, text_piece)
        assert list(piece.line) == [2]


# -- memory and the fast path ---------------------------------------------------------------


def _raster(path: Path, rows: int) -> Path:
    lines = ["UNITS/MM", "MULTAX/ON", "FEDRAT/MMPM,2000", "RAPID"]
    for k in range(rows):
        if k % 2500 == 1250:
            lines += ["FEDRAT/MMPM,800", "RAPID"]
        x, y = (k % 97) * 0.5, (k // 97) * 0.5
        lines.append(f"GOTO/{x:.4f},{y:.4f},{math.sin(k) * 3:.4f},0.000000,0.600000,0.800000")
    path.write_text("\n".join(lines) + "\nFINI\n")
    return path


def test_long_file_streams_in_bounded_memory(tmp_path):
    """A 40000-point file: the same points, and a fraction of read_cl's memory."""
    path = _raster(tmp_path / "raster.apt", 40000)
    tracemalloc.start()
    try:
        whole = read_cl(path)
        whole_peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.reset_peak()
        base = tracemalloc.get_traced_memory()[0]
        offset = 0
        for piece in read_cl_chunks(path, max_points=1000, _text_piece=1 << 16):
            for name in FIELDS:
                part = getattr(whole, name)[offset : offset + len(piece)]
                assert getattr(piece, name).tobytes() == part.tobytes()
            offset += len(piece)
        streamed_peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert offset == len(whole) == 40000
    assert streamed_peak < whole_peak / 4, (streamed_peak, whole_peak)


def test_long_file_is_read_in_bulk(tmp_path, monkeypatch):
    """The streaming reader reads runs of GOTO records in bulk, as read_cl does: only the
    records after RAPID, and short ends of runs cut by a text piece, one by one."""
    path = _raster(tmp_path / "raster.apt", 5000)
    lines: list[int] = []
    one_by_one = apt_module._AptInterpreter._goto
    monkeypatch.setattr(
        apt_module._AptInterpreter,
        "_goto",
        lambda self, record: lines.append(record.line) or one_by_one(self, record),
    )
    read_cl(path)
    assert lines == [5, 1257, 3759]
    for text_piece, most in [(1 << 23, 3), (1 << 12, 200)]:
        lines.clear()
        pieces = check_file(path, 700, text_piece)
        assert pieces is not None and len(pieces) == 8
        assert 3 <= len(lines) // 2 <= most  # check_file reads with read_cl too


@pytest.mark.slow
def test_benchmark_job_in_default_text_pieces(tmp_path):
    """The benchmark's hemisphere raster, 200000 points (12 MB): default text pieces cut it
    inside runs of GOTO records; the pieces are read_cl's toolpath."""
    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("make_large_cl", root / "bench/make_large_cl.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    path = module.write_hemisphere(200_000, tmp_path / "hemisphere.apt")
    assert path.stat().st_size > 1 << 23  # more than one text piece
    for max_points in (250_000, 30_000):
        pieces = check_file(path, max_points, 1 << 23)
        assert pieces is not None and all(p.multiaxis for p in pieces)


# -- found by fuzzing (tests/test_fuzz_readers.py) ---------------------------------------------


@pytest.mark.parametrize(
    ("data", "format"),
    [
        (b"\x01\r\x00", "plain"),  # a bad line, then a NUL in the next piece
        (b"1 2\n" + b"1 2 3\n" * 20 + b"\x00", "plain"),
        (b"GOTO/1,2\nFINI\n\x00", "apt"),  # a bad record, then a NUL after FINI
        (b"GOTO/1,2,3\nFEDRAT/-1\n" + b"GOTO/1,2,3\n" * 50 + b"FINI\nx\x00", None),
    ],
)
@pytest.mark.parametrize("text_piece", [1, 4, 1 << 23])
def test_a_nul_after_a_bad_record_is_the_error(tmp_path, data, format, text_piece):
    """read_cl refuses a NUL anywhere before it reads a record; the pieces raise the same
    error, not the error of a record before the NUL."""
    path = tmp_path / "nul.cl"
    path.write_bytes(data)
    with pytest.raises(CLDataError, match="a NUL byte"):
        read_cl(path, format=format)
    assert check_file(path, 1, text_piece, format=format) is None


@pytest.mark.parametrize("text_piece", [1, 2, 3, 64])
@pytest.mark.parametrize(
    ("data", "text"),
    [
        ("\ufeffGOTO/1,2,3\n".encode("utf-16-le"), "GOTO/1,2,3\n"),
        # a second mark is text (a zero-width no-break space), whole and in pieces
        ("\ufeff\ufeffGOTO/1,2,3\n".encode("utf-16-le"), "\ufeffGOTO/1,2,3\n"),
        (b"\xff\xfeGOTO/", None),  # an odd byte: replaced
    ],
)
def test_a_wide_file_in_pieces_of_one_character(tmp_path, data, text, text_piece):
    """The byte-order mark of a UTF-16 file read one character at a time: its piece is empty
    once the mark is dropped, which is not the end of the file (the whole text was lost)."""
    path = tmp_path / "wide.apt"
    path.write_bytes(data)
    expected = data[2:].decode("utf-16-le", "replace")
    assert text is None or expected == text
    assert "".join(text_pieces(str(path), text_piece)) == expected
    check_file(path, 1, text_piece)


# -- the streaming reader's facts pass stops at the units --------------------------------------


def _far(tail: list[str], head: tuple[str, ...] = ("UNITS/MM", "MULTAX/ON")) -> str:
    """A file whose first UNITS record is at its start, then more GOTO lines than a few text
    parts hold, then ``tail``."""
    run = [f"GOTO/{k * 0.01:.4f},0,5,0,0,1" for k in range(3000)]
    end = [] if tail[-1].endswith("$") else ["FINI"]  # (an open record at the very end)
    return "\n".join([*head, "FEDRAT/MMPM,500", *run, *tail, *end]) + "\n"


@pytest.mark.parametrize("text_piece", [64, 4096, 1 << 20])
@pytest.mark.parametrize(
    "tail",
    [
        # an arc, NX evidence after it: the arc's sense is the NX one, as in the whole read
        ["CIRCLE/0.5,30,5,0,0,1,0.5", "GOTO/30.5,30,5", "TOOL PATH/OP1,TOOL,T1", "GOTO/1,1,5"],
        # an arc and no NX evidence: the APT sense
        ["CIRCLE/0.5,30,5,0,0,1,0.5", "GOTO/30.5,30,5"],
        # a bad record, then a record left open by the end of the file: the whole read says
        # the end first (before it interprets any record)
        ["GOTO/1,x,3", "GOTO/1,2,3", "GOTO/1,2,$"],
        # only the open record at the end
        ["GOTO/1,2,$"],
    ],
)
def test_the_units_pass_stops_early_and_the_reading_is_the_same(
    tmp_path: Path, tail: list[str], text_piece: int
) -> None:
    path = tmp_path / "far.apt"
    path.write_text(_far(tail))
    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(apt_module, "_STREAM_PART", 4096)
        units, nx, complete = apt_module._apt_facts(str(path), text_piece, whole=False)
        assert units == ("mm", 1) and (nx, complete) == (None, False)
        check_file(path, 500, text_piece, format="apt", chord_tolerance=0.05)
    whole = outcome(lambda: read_cl(path, format="apt", chord_tolerance=0.05))
    if tail[0].startswith("CIRCLE") and not isinstance(whole, tuple):
        arcs = [e for e in whole.events if e.kind == "arc"]
        nx_sense = any(line.startswith("TOOL PATH") for line in tail)
        assert arcs and (arcs[0].data["normal"][2] < 0) == nx_sense  # clockwise in NX
