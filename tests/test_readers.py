"""Tests of the CL data readers (urdfpost.readers)."""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import urdfpost.readers as readers_module
import urdfpost.readers.apt as apt_module
from urdfpost.errors import CLDataError
from urdfpost.readers import FORMATS, Format, detect_format, read_cl, read_cl_chunks, read_cl_text
from urdfpost.readers._geometry import max_arc_step
from urdfpost.toolpath import Motion
from urdfpost.units import MM_PER_INCH

DATA = Path(__file__).parent / "data" / "cl"
REAL = Path(__file__).parents[1].parent / "shared" / "testdata" / "cl"
BALLMILL = REAL / "nx_variable_axis_ballmill_inch.cls"
PROJECT2 = REAL / "nx_project2_15ops_inch.cls"


def real_file(path: Path) -> Path:
    if not path.is_file():
        pytest.skip(f"real CL sample {path} absent (it lives in ../shared/testdata/cl)")
    return path


def apt(text: str, **kwargs):
    """Read APT text under the name 'src.apt'."""
    return read_cl_text(text, source="src.apt", format="apt", **kwargs)


APT_SENSE = "counter-clockwise about the circle axis (right-hand rule), the APT convention"
NX_SENSE = "clockwise about the circle axis, the NX CLSF convention"


def sense_note(line: int, reason: str = "", source: str = "src.apt") -> str:
    """The warning of the first CIRCLE (line ``line``) on the sense inferred: APT when
    ``reason`` is "", else NX CLSF for that reason ("the NX record TOOL PATH at line 1")."""
    sense = NX_SENSE if reason else APT_SENSE
    return (
        f"{source}:{line}: CIRCLE sense inferred, not declared: arcs turn {sense} "
        f"({reason or 'no NX CLSF record in the file'}); each arc is checked against the feed "
        "moves before and after it"
    )


# -- an independent, minimal view of an NX listing, for cross-checking the reader -------------


def raw_records(path: Path) -> list[tuple[int, str]]:
    """(line, record text without trailing $$ comment) of every non-blank line."""
    out = []
    lines = re.split(r"\r\n|\r|\n", path.read_text())
    for number, line in enumerate(lines, start=1):
        code = line.split("$$")[0].strip()
        if code:
            out.append((number, code))
    return out


def goto_values(code: str) -> list[float]:
    return [float(v) for v in code.split("/", 1)[1].split(",")]


# -- API ---------------------------------------------------------------------------------------


def test_formats_registry():
    assert list(FORMATS) == ["apt", "plain"]
    assert all(name == entry.name for name, entry in FORMATS.items())
    assert [name for name, entry in FORMATS.items() if entry.fallback] == ["plain"]
    assert FORMATS["apt"].read_text is apt_module.read_apt_text
    assert FORMATS["apt"].arcs and not FORMATS["plain"].arcs


_PLAIN = "from urdfpost.readers.plain import FORMAT\n"
_CSV_FORMAT = """
from urdfpost.readers import read_plain_text
from urdfpost.readers._format import Format


def read_csv_text(text, *, source="<string>", units=None, chord_tolerance=0.001):
    return read_plain_text(text.replace(";", " "), source=source, units=units)


def read_csv_stream(source, *, max_points, units, chord_tolerance, text_piece):
    with open(source) as handle:
        yield read_csv_text(handle.read(), source=source, units=units)


FORMAT = Format("csv", "x;y;z points", read_csv_text, read_csv_stream)
"""


def format_package(root: Path, name: str, **modules: str) -> tuple[str, list[str]]:
    """A package ``name`` under ``root`` with the given modules: its name and path."""
    package = root / name
    package.mkdir()
    (package / "__init__.py").write_text("")
    for module, text in modules.items():
        (package / f"{module}.py").write_text(text)
    return name, [str(package)]


def test_a_format_is_one_module(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    name, path = format_package(
        tmp_path, "cl_formats", zcsv=_CSV_FORMAT, plain=_PLAIN, _helper="X = 1\n"
    )
    found = readers_module._discover(name, path)
    assert list(found) == ["csv", "plain"]  # by name; _helper is no format
    monkeypatch.setattr(readers_module, "FORMATS", found)
    toolpath = read_cl_text("1;2;3\n4;5;6\n", format="CSV")
    assert toolpath.tip.tolist() == [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
    assert detect_format("GOTO/1,2,3\n") == "plain"  # no APT without its module
    cl = tmp_path / "a.csv"
    cl.write_text("1;2;3\n")
    assert [len(p) for p in read_cl_chunks(cl, max_points=5, format="csv")] == [1]
    with pytest.raises(ValueError, match=r"format: expected one of csv, plain, got 'apt'"):
        read_cl_text("GOTO/1,2,3\n", format="apt")


@pytest.mark.parametrize(
    ("package", "modules", "message"),
    [
        ("cl_bad1", {"plain": _PLAIN, "csv": "X = 1\n"}, r"cl_bad1\.csv: expected a module-level"),
        (
            "cl_bad2",
            {"plain": _PLAIN, "plain2": _PLAIN},
            r"plain2: format 'plain' is declared",
        ),
        (
            "cl_bad3",
            {"apt": "from urdfpost.readers.apt import FORMAT\n"},
            r"cl_bad3: expected one fallback format, got \[\]",
        ),
    ],
)
def test_format_discovery_errors(tmp_path, monkeypatch, package, modules, message):
    monkeypatch.syspath_prepend(str(tmp_path))
    name, path = format_package(tmp_path, package, **modules)
    with pytest.raises(TypeError, match=message):
        readers_module._discover(name, path)


def test_format_entries_are_frozen():
    with pytest.raises(AttributeError):
        FORMATS["apt"].name = "x"  # type: ignore[misc]
    assert isinstance(FORMATS["plain"], Format)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("GOTO/1,2,3\n", "apt"),
        ("  goto / 1, 2, 3", "apt"),
        ("TOOL PATH/OP,TOOL,T1\n", "apt"),
        ("$$ only a comment\n", "apt"),
        ("1 2 3\n4 5 6 0 0 1\n", "plain"),
        ("# a/b comment\n1,2,3\n", "plain"),
        ("", "plain"),
    ],
)
def test_detect_format(text, expected):
    assert detect_format(text) == expected


def test_read_cl_missing_file(tmp_path):
    missing = tmp_path / "missing.cls"
    with pytest.raises(CLDataError, match=r"missing\.cls: cannot read: ") as info:
        read_cl(missing)
    assert info.value.line == 0
    assert info.value.path == str(missing)


def test_read_cl_detects_format_and_names_source(tmp_path):
    path = tmp_path / "a.txt"
    path.write_text("0 0 0\n1 0 0\n")
    tp = read_cl(path)
    assert tp.source == str(path)
    assert len(tp) == 2


@pytest.mark.parametrize(
    "kwargs",
    [{"format": "gcode"}, {"units": "furlong"}, {"chord_tolerance": 0.0}, {"chord_tolerance": -1}],
)
def test_bad_arguments(kwargs):
    with pytest.raises(ValueError):
        read_cl_text("GOTO/1,2,3", **kwargs)


# -- real NX files -----------------------------------------------------------------------------


def test_nx_ballmill_file():
    path = real_file(BALLMILL)
    tp = read_cl(path)
    records = raw_records(path)
    gotos = []  # (line, values, rapid)
    rapid = False
    for line, code in records:
        if code.upper() == "RAPID":
            rapid = True
        elif code.upper().startswith("GOTO/"):
            gotos.append((line, goto_values(code), rapid))
            rapid = False
    assert len(gotos) == 348
    assert len(tp) == 348
    assert tp.units == "inch"
    assert tp.multiaxis
    assert tp.warnings == ()
    np.testing.assert_array_equal(tp.line, [g[0] for g in gotos])
    expected_motion = [Motion.RAPID if g[2] else Motion.FEED for g in gotos]
    np.testing.assert_array_equal(tp.motion, expected_motion)
    assert (tp.motion == Motion.RAPID).sum() == 3
    # MSYS/3,3,0 with identity axes says where the MCS lies in the part: informational, the
    # GOTO values are already in the MCS (NX's own post writes them as they are)
    expected_tip = np.array([g[1][:3] for g in gotos]) * MM_PER_INCH
    np.testing.assert_allclose(tp.tip, expected_tip, rtol=0, atol=1e-9)
    axis = np.array([0.0, 0.0, 1.0])
    for k, (_, values, _) in enumerate(gotos):
        if len(values) == 6:
            axis = np.array(values[3:]) / np.linalg.norm(values[3:])
        np.testing.assert_allclose(tp.axis[k], axis, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(tp.axis, axis=1), 1.0, atol=1e-12)
    assert sum(len(g[1]) == 6 for g in gotos) == 329
    # feeds: NaN on rapids and before the first FEDRAT, then 10 IPM
    feed_line = next(line for line, code in records if code.startswith("FEDRAT"))
    after = (tp.motion == Motion.FEED) & (tp.line > feed_line)
    np.testing.assert_allclose(tp.feed[after], 10 * MM_PER_INCH)
    assert np.isnan(tp.feed[tp.motion == Motion.RAPID]).all()
    kinds = [(e.kind, e.index, e.line) for e in tp.events]
    assert kinds == [("operation", 0, 1), ("cutter", 0, 2), ("msys", 0, 3), ("comment", 0, 4)]
    assert tp.events[0].data == {"name": "NORM_PART", "tool_name": "BALL_MILL_1.00"}
    cutter = tp.events[1].data
    assert cutter["diameter"] == pytest.approx(25.4)
    assert cutter["corner_radius"] == pytest.approx(12.7)
    assert cutter["length"] == pytest.approx(76.2)
    msys = tp.events[2].data
    assert msys["mcs"] == 0 and msys["transformed"] is False
    np.testing.assert_allclose(msys["origin"], [3 * MM_PER_INCH, 3 * MM_PER_INCH, 0], atol=1e-12)
    np.testing.assert_array_equal(msys["rotation"], np.eye(3))
    assert msys["text"] == "MCS 0 origin 3 3 0 inch, x-axis 1 0 0, z-axis 0 0 1"
    assert tp.events[3].data == {"text": "centerline data"}


@pytest.fixture(scope="module")
def project2():
    path = real_file(PROJECT2)
    return path, read_cl(path), raw_records(path)


def test_nx_project2_counts_and_units(project2):
    path, tp, records = project2
    assert not path.read_bytes().endswith(b"\n")  # the file has no final newline
    goto_lines = [line for line, code in records if code.startswith("GOTO/")]
    circle_lines = [line for line, code in records if code.startswith("CIRCLE/")]
    assert len(goto_lines) == 10585
    assert len(circle_lines) == 146
    assert tp.units == "inch"
    assert tp.multiaxis
    # the sense of the first CIRCLE is said once; every arc is tangent to its feed moves in it
    assert tp.warnings == (sense_note(22, "an NX listing line at line 2", str(path)),)
    # every GOTO that does not end an arc is one point on its own line, in file order
    ends = set()
    for (_, first), (line, second) in itertools.pairwise(records):
        if first.startswith("CIRCLE/"):
            assert second.startswith("GOTO/")
            ends.add(line)
    plain = [line for line in goto_lines if line not in ends]
    on_goto = np.isin(tp.line, plain)
    np.testing.assert_array_equal(tp.line[on_goto], plain)
    on_circle = np.isin(tp.line, circle_lines)
    assert on_goto.sum() + on_circle.sum() == len(tp)
    extra = int(on_circle.sum()) - len(circle_lines)
    assert extra > 0
    assert len(tp) == 10585 + extra
    assert np.all(np.diff(tp.line) >= 0)
    assert (tp.motion == Motion.RAPID).sum() == sum(code == "RAPID" for _, code in records)
    np.testing.assert_allclose(np.linalg.norm(tp.axis, axis=1), 1.0, atol=1e-12)


def test_nx_project2_points_are_file_values_in_mm(project2):
    _, tp, records = project2
    # inline "$$ x,y,z" contact points are ignored: the tip is the GOTO's first three values
    by_line = {line: goto_values(code) for line, code in records if code.startswith("GOTO/")}
    text_lines = PROJECT2.read_text().splitlines()
    assert sum("GOTO/" in line and "$$" in line for line in text_lines) == 2445
    goto_points = np.isin(tp.line, list(by_line))
    expected = np.array([by_line[line][:3] for line in tp.line[goto_points]]) * MM_PER_INCH
    np.testing.assert_allclose(tp.tip[goto_points], expected, rtol=0, atol=1e-9)
    horizontal = np.abs(tp.axis[:, 2]) < 1e-12
    assert horizontal.any()  # tool axes down to exactly horizontal (k = 0)


def test_nx_project2_arcs(project2):
    _, tp, records = project2
    tol = 0.01
    checked = 0
    for k, (line, code) in enumerate(records):
        if not code.startswith("CIRCLE/"):
            continue
        values = code.split("/", 1)[1].split(",")
        centre = np.array([float(v) for v in values[:3]]) * MM_PER_INCH
        normal = np.array([float(v) for v in values[3:6]])
        normal /= np.linalg.norm(normal)
        radius = float(values[6]) * MM_PER_INCH
        end = np.array(goto_values(records[k + 1][1])[:3]) * MM_PER_INCH
        idx = np.flatnonzero(tp.line == line)
        assert idx.size >= 1
        points = tp.tip[idx]
        start = tp.tip[idx[0] - 1]
        # the arc ends exactly on the GOTO after the CIRCLE
        np.testing.assert_allclose(points[-1], end, rtol=0, atol=1e-12)
        # every point on the circle's cylinder within the chord tolerance
        rel = np.vstack([start, points]) - centre
        height = rel @ normal
        radial = rel - height[:, None] * normal
        dist = np.linalg.norm(radial, axis=1)
        assert np.abs(dist - radius).max() <= tol
        # height along the axis goes linearly from start to end (a plane or a helix)
        if abs(height[0] - height[-1]) > 1e-3:
            assert np.all(np.diff(height) * np.sign(height[-1] - height[0]) > 0)
        assert np.all(height >= min(height[0], height[-1]) - 1e-9)
        assert np.all(height <= max(height[0], height[-1]) + 1e-9)
        # NX turns clockwise about (i,j,k): each step turns about -normal
        turn = np.cross(radial[:-1], radial[1:]) @ -normal
        assert np.all(turn > 0)
        # chord error (sagitta of each step) within the tolerance
        cosine = np.sum(radial[:-1] * radial[1:], axis=1) / (dist[:-1] * dist[1:])
        step = np.arccos(np.clip(cosine, -1, 1))
        assert np.all(dist.max() * (1 - np.cos(step / 2)) <= tol + 1e-12)
        # feed moves with the operation's feed, current tool axis
        assert np.all(tp.motion[idx] == Motion.FEED)
        assert np.all(tp.feed[idx] > 0)
        np.testing.assert_allclose(
            tp.axis[idx], np.broadcast_to(tp.axis[idx[0] - 1], (idx.size, 3))
        )
        checked += 1
    assert checked == 146


def test_nx_project2_helix_times(project2):
    """CIRCLE ... TIMES,7: a helical ramp of 6 turns plus the partial arc, at a 3 degree ramp."""
    _, tp, _ = project2
    idx = np.flatnonzero(tp.line == 4641)
    normal = np.array([0.0, -0.9922779, -0.1240347])
    d = np.diff(tp.tip[idx[0] - 1 : idx[-1] + 1], axis=0)
    along = d @ normal
    across = np.linalg.norm(d - along[:, None] * normal, axis=1)
    np.testing.assert_allclose(np.degrees(np.arctan(np.abs(along) / across)), 3.0, atol=0.01)
    radial = tp.tip[idx] - np.array([1.9949, 3.6307, 1.9391]) * MM_PER_INCH
    radial -= (radial @ normal)[:, None] * normal
    swept = np.sum(
        np.arctan2(
            np.cross(radial[:-1], radial[1:]) @ -normal, np.sum(radial[:-1] * radial[1:], axis=1)
        )
    )
    assert 6 < swept / (2 * math.pi) < 7


def test_nx_project2_events(project2):
    _, tp, _ = project2
    tools = [e for e in tp.events if e.kind == "tool"]
    assert [e.data["number"] for e in tools] == [1, 2, 1, 3]
    assert [e.data["name"] for e in tools] == [
        "MILL_0.120RAD",
        "MILL_0RAD",
        "MILL_0.120RAD",
        "BALL_MILL_0.24DIA",
    ]
    assert [round(e.data["diameter"] / MM_PER_INCH, 4) for e in tools] == [0.75, 0.375, 0.75, 0.24]
    assert [e.line for e in tools] == [13, 4632, 4737, 5323]
    assert [e.data["adjust"] for e in tools] == [1, 2, 1, 3]  # LOAD/TOOL,n,ADJUST,n
    operations = [e.data["name"] for e in tp.events if e.kind == "operation"]
    assert len(operations) == 15
    assert operations[0] == "CAVITY_MILL" and operations[-1] == "ROTARY_FLOOR"
    comments = [e.data["text"] for e in tp.events if e.kind == "comment"]
    assert len(comments) == 20
    assert "centerline and contact point" in comments
    assert {e.kind for e in tp.events} == {"operation", "cutter", "tool", "comment", "msys", "arc"}
    # every CIRCLE record, before the points interpolated on it
    arcs = [e for e in tp.events if e.kind == "arc"]
    assert len(arcs) == 146
    assert all((tp.line[e.index : e.index + e.data["points"]] == e.line).all() for e in arcs)
    # one MSYS per operation, all of the same MCS (at the part's zero): no point is moved
    msys = [e for e in tp.events if e.kind == "msys"]
    assert len(msys) == 15
    assert {(e.data["mcs"], e.data["transformed"]) for e in msys} == {(0, False)}
    assert {e.data["origin"] for e in msys} == {(0.0, 0.0, 0.0)}
    assert len(tp.warnings) == 1 and "CIRCLE sense inferred" in tp.warnings[0]
    # each tool event precedes the first motion of its operation
    for event in tools:
        assert tp.line[event.index] > event.line


# -- APT family: syntax ------------------------------------------------------------------------


def test_creo_continuation_equals_single_lines():
    split = read_cl(DATA / "creo_split.ncl")
    single = read_cl(DATA / "creo_oneline.ncl")
    np.testing.assert_array_equal(split.tip, single.tip)
    np.testing.assert_array_equal(split.axis, single.axis)
    np.testing.assert_array_equal(split.feed, single.feed)
    np.testing.assert_array_equal(split.motion, single.motion)
    assert [e.kind for e in split.events] == [e.kind for e in single.events]
    # a continued record's line is its first line
    assert list(split.line) == [13, 16, 18, 19]
    assert split.units == "mm"
    np.testing.assert_allclose(split.axis[1], [0, math.sqrt(0.5), math.sqrt(0.5)])
    np.testing.assert_allclose(split.axis[2], split.axis[1])  # modal
    assert list(split.motion) == [Motion.RAPID, Motion.FEED, Motion.FEED, Motion.FEED]
    np.testing.assert_allclose(split.feed[1:], 500.0)
    assert split.warnings == (
        f"{DATA / 'creo_split.ncl'}:5: unknown record 'MACHIN / UNCX01, 1' carried as a comment",
    )
    kinds = [e.kind for e in split.events]
    assert kinds == [
        "comment", "comment", "partno", "comment", "unknown", "comment",
        "tool", "comment", "spindle", "coolant", "coolant", "spindle",
    ]  # fmt: skip
    assert split.events[2].data == {"text": "SAMPLE"}
    assert split.events[6].data == {"number": 1}
    assert split.events[8].data == {"rpm": 1000.0, "direction": "cw"}
    assert split.events[9].data == {"mode": "flood"}
    assert split.events[11].data == {"rpm": 0.0, "direction": "off"}
    assert split.events[11].index == 4


def test_catia_sample():
    tp = read_cl(DATA / "catia_style.aptsource")
    src = str(DATA / "catia_style.aptsource")
    assert tp.units == "mm"
    assert tp.multiaxis
    assert tp.warnings == (
        f"{src}:12: unknown record 'TPRINT/T1 End Mill D 10,T1 End Mill D 10,MfgTool.1' "
        "carried as a comment",
        f"{src}:13: LOADTL: '1,1' after the tool number not understood; ignored (LENGTH and "
        "ADJUST are read)",
    )
    np.testing.assert_allclose(
        tp.tip, [[0, 0, 100], [10, 10, 20], [10, 10, 0], [50, 10, 0], [60, 10, 0]]
    )
    assert list(tp.motion) == [Motion.RAPID, Motion.RAPID, Motion.FEED, Motion.FEED, Motion.FEED]
    np.testing.assert_allclose(tp.feed[2:], [1000.0, 1000.0, 0.1 * 3000])
    np.testing.assert_allclose(tp.axis[3], [0, 0.5, 0.866025] / np.linalg.norm([0, 0.5, 0.866025]))
    by_kind = {}
    for event in tp.events:
        by_kind.setdefault(event.kind, []).append(event)
    assert by_kind["partno"][0].data == {"text": "PART TO BE MACHINED"}
    assert by_kind["cutter"][0].data == {"diameter": 10.0, "corner_radius": 2.0, "length": 100.0}
    assert by_kind["tool"][0].data == {  # (the cutter's length is no gauge length)
        "number": 1,
        "diameter": 10.0,
        "corner_radius": 2.0,
        "cutter_length": 100.0,
    }
    assert by_kind["spindle"][0].data == {"rpm": 3000.0, "direction": "cw"}
    assert by_kind["coolant"][0].data == {"mode": "mist"}
    assert by_kind["insert"][0].data == {"text": "G90 G54  (verbatim)"}
    assert [e.data for e in by_kind["stop"]] == [{"optional": True}, {"optional": False}]
    assert by_kind["home"][0].index == 5
    assert by_kind["comment"][-1].data == {"text": "MEASURE HERE"}
    assert by_kind["comment"][-1].index == 4


def test_trailing_comment_is_not_an_event():
    tp = apt("GOTO/1,2,3 $$ 4,5,6\nGOTO/7,8,9$$ contact")
    np.testing.assert_allclose(tp.tip, [[1, 2, 3], [7, 8, 9]])
    assert tp.events == ()
    assert tp.warnings == ()


def test_whole_line_comment_event_index():
    tp = apt("GOTO/1,2,3\n$$ between\nGOTO/4,5,6\n$$ after\n")
    assert [(e.kind, e.index, e.line, e.data["text"]) for e in tp.events] == [
        ("comment", 1, 2, "between"),
        ("comment", 2, 4, "after"),
    ]


def test_modal_tool_axis_and_multiaxis_flag():
    tp = apt("GOTO/0,0,0\nGOTO/1,0,0,0,0.6,0.8\nGOTO/2,0,0\n")
    np.testing.assert_allclose(tp.axis, [[0, 0, 1], [0, 0.6, 0.8], [0, 0.6, 0.8]])
    assert tp.multiaxis
    assert not apt("GOTO/0,0,0\nGOTO/1,0,0\n").multiaxis
    assert apt("MULTAX\nGOTO/0,0,0\n").multiaxis
    assert apt("MULTAX/ON\nGOTO/0,0,0\n").multiaxis
    assert not apt("MULTAX/OFF\nGOTO/0,0,0\n").multiaxis


def test_non_unit_axis_is_normalised_with_warning():
    tp = apt("GOTO/0,0,0,0,0,2\n")
    np.testing.assert_allclose(tp.axis, [[0, 0, 1]])
    assert tp.warnings == ("src.apt:1: tool axis (0, 0, 2) has length 2; normalised",)


def test_msys_rotation_hand_computed():
    # X axis = part +Y, Y axis = part -X (so Z = part +Z): a 90 degree turn about Z. One MCS:
    # informational, points and axes as written, the MCS in the event
    tp = apt("MSYS/10,20,30,0,1,0,-1,0,0\nGOTO/1,2,3,1,0,0\nGOTO/0,0,0\n")
    np.testing.assert_allclose(tp.tip, [[1, 2, 3], [0, 0, 0]], atol=0)
    np.testing.assert_allclose(tp.axis, [[1, 0, 0], [1, 0, 0]], atol=0)
    (event,) = tp.events
    assert (event.kind, event.index, event.line) == ("msys", 0, 1)
    np.testing.assert_allclose(event.data["origin"], [10, 20, 30], atol=1e-12)
    np.testing.assert_allclose(
        event.data["rotation"], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12
    )
    assert event.data["text"] == "MCS 0 origin 10 20 30 mm, x-axis 0 1 0, z-axis 0 0 1"
    assert tp.warnings == ()
    # X = part X, Y = part Z, so Z = X x Y = part -Y; axes given unnormalised
    tp = apt("MSYS/0,0,0,2,0,0,0,0,5\nGOTO/1,2,3\n")
    np.testing.assert_allclose(tp.tip, [[1, 2, 3]], atol=0)
    np.testing.assert_allclose(tp.axis, [[0, 0, 1]], atol=0)
    np.testing.assert_allclose(tp.events[0].data["rotation"], [[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    # inch, a second MSYS of another MCS (1 in along X from the first): its points are
    # transformed into the first MCS, p_first = p_second + (0 - 1 in, 0, 0)
    tp = apt("UNITS/INCHES\nMSYS/1,0,0,1,0,0,0,1,0\nGOTO/1,0,0\nMSYS/0,0,0,1,0,0,0,1,0\nGOTO/1,0,0")
    np.testing.assert_allclose(tp.tip, [[MM_PER_INCH, 0, 0], [0, 0, 0]], atol=1e-12)
    assert [(e.data["mcs"], e.data["transformed"]) for e in tp.events] == [(0, False), (1, True)]
    assert tp.warnings == (
        "src.apt:4: MSYS at line 4 differs from the first MCS (line 2): points transformed "
        "into the first MCS",
    )


def test_msys_not_orthogonal_warns():
    tp = apt("MSYS/0,0,0,1,0,0,0.1,1,0\nGOTO/0,1,0\n")
    np.testing.assert_allclose(tp.tip, [[0, 1, 0]], atol=1e-12)
    assert tp.warnings == ("src.apt:1: MSYS axes are not orthogonal; orthonormalised",)


@pytest.mark.parametrize("ending", ["", "\n", "\n\n  \n"])
def test_missing_or_extra_final_newline(ending):
    tp = apt("GOTO/1,2,3\nGOTO/4,5,$\n6" + ending)
    np.testing.assert_allclose(tp.tip, [[1, 2, 3], [4, 5, 6]])


def test_crlf_and_cr_line_endings():
    text = "$$ c\nRAPID\nGOTO/1,2,3\nGOTO/4,5,$\n6,0,0,1\nFOO/1\n"
    lf = apt(text)
    for newline in ("\r\n", "\r"):
        other = apt(text.replace("\n", newline))
        np.testing.assert_array_equal(other.tip, lf.tip)
        np.testing.assert_array_equal(other.line, lf.line)
        assert other.events == lf.events
        assert other.warnings == lf.warnings


@pytest.mark.parametrize("size", [1 << 23, 7])
def test_a_file_with_cr_line_ends_is_detected_as_apt(tmp_path, size):
    """CR line ends (no LF) and a first line that is no APT record (``PARTNO`` has no slash):
    the file is recognised as APT by its later lines, whole and in pieces that end at a CR,
    and read as with LF (it was read as plain text: "line 1: expected 3 or 6 values")."""
    from urdfpost.readers import detect_file_format

    text = "PARTNO CR ONLY\nUNITS/MM\nMULTAX/ON\nGOTO/1,2,3,0,0,1\nGOTO/4,5,6,0,0,1\nFINI\n"
    lf, cr = tmp_path / "lf.apt", tmp_path / "cr.apt"
    lf.write_bytes(text.encode())
    cr.write_bytes(text.replace("\n", "\r").encode())
    assert detect_file_format(str(cr), size) == "apt"
    want, got = read_cl(lf), read_cl(cr)
    np.testing.assert_array_equal(got.tip, want.tip)
    np.testing.assert_array_equal(got.line, want.line)
    (piece,) = read_cl_chunks(cr, max_points=10, _text_piece=size)
    np.testing.assert_array_equal(piece.tip, want.tip)


def test_crlf_file(tmp_path):
    path = tmp_path / "crlf.cls"
    path.write_bytes(b"UNITS/MM\r\nGOTO/1,2,3\r\nGOTO/4,5,$\r\n6\r\nFINI")
    tp = read_cl(path)
    np.testing.assert_allclose(tp.tip, [[1, 2, 3], [4, 5, 6]])
    assert list(tp.line) == [2, 3]
    assert tp.warnings == ()


def test_case_insensitive_keywords():
    tp = apt("units/inches\nrapid\ngoto/1,0,0\nFedRat/ipm,10\nGoto/2,0,0\n")
    assert tp.units == "inch"
    assert list(tp.motion) == [Motion.RAPID, Motion.FEED]
    np.testing.assert_allclose(tp.feed[1], 254.0)


def test_unknown_record_is_comment_and_warning():
    tp = apt("GOTO/0,0,0\nAUXFUN/12\nGOTO/1,0,0\n")
    assert [(e.kind, e.index, e.line, e.data) for e in tp.events] == [
        ("unknown", 1, 2, {"text": "AUXFUN/12"})
    ]
    assert tp.warnings == ("src.apt:2: unknown record 'AUXFUN/12' carried as a comment",)


@pytest.mark.parametrize(
    "record",
    [
        "COOLNT/TAPKUL",
        "SPINDL/SFM,300",
        "RAPID/ON",
        "LOAD/FIXTURE,1",
        "TLDATA/DRILL,5,118",
        "1 2 3",
    ],
)
def test_partly_understood_records_are_unknown(record):
    tp = apt(record + "\nGOTO/0,0,0\n")
    assert [e.kind for e in tp.events] == ["unknown"]
    assert tp.warnings == (f"src.apt:1: unknown record '{record}' carried as a comment",)


def test_rapid_applies_to_next_goto_only():
    tp = apt("FEDRAT/100\nRAPID\nGOTO/0,0,10\nGOTO/0,0,0\nGOTO/1,0,0\nRAPID\nGOTO/1,0,10\n")
    assert list(tp.motion) == [Motion.RAPID, Motion.FEED, Motion.FEED, Motion.RAPID]
    np.testing.assert_array_equal(np.isnan(tp.feed), [True, False, False, True])
    np.testing.assert_allclose(tp.feed[1:3], 100.0)


def test_from_is_a_rapid_point():
    tp = apt("FROM/0,0,100,0,0,1\nGOTO/0,0,0\n")
    assert list(tp.motion) == [Motion.RAPID, Motion.FEED]
    assert np.isnan(tp.feed).all()


@pytest.mark.parametrize(
    ("records", "units", "feed"),
    [
        ("FEDRAT/100", "mm", 100.0),
        ("FEDRAT/MMPM,100", "mm", 100.0),
        ("FEDRAT/100,MMPM", "mm", 100.0),
        ("FEDRAT/IPM,10", "inch", 254.0),
        ("FEDRAT/10,IPM", "inch", 254.0),
        ("FEDRAT / 10.000000, IPM", "inch", 254.0),
        ("UNITS/INCHES\nFEDRAT/10", "inch", 254.0),
        ("SPINDL/1000,CLW\nFEDRAT/MMPR,0.1", "mm", 100.0),
        ("SPINDL/RPM,2000,CCLW\nFEDRAT/0.002,IPR", "inch", 0.002 * 2000 * 25.4),
    ],
)
def test_fedrat_variants(records, units, feed):
    tp = apt(records + "\nGOTO/1,0,0\n")
    assert tp.units == units
    np.testing.assert_allclose(tp.feed, [feed])
    np.testing.assert_allclose(tp.tip, [[1 * (25.4 if units == "inch" else 1), 0, 0]])


def test_feed_per_rev_without_spindle_warns_until_speed_known():
    tp = apt("FEDRAT/MMPR,0.1\nGOTO/1,0,0\nSPINDL/500\nGOTO/2,0,0\nSPINDL/OFF\nGOTO/3,0,0")
    np.testing.assert_array_equal(np.isnan(tp.feed), [True, False, True])
    assert tp.feed[1] == pytest.approx(50.0)
    assert tp.warnings == (
        "src.apt:1: feed per revolution with no spindle speed; feed left unset until a SPINDL "
        "record",
    )


def test_units_given_win_over_the_file():
    assert apt("GOTO/1,0,0", units="inch").units == "inch"
    np.testing.assert_allclose(apt("GOTO/1,0,0", units="inch").tip, [[25.4, 0, 0]])
    assert apt("GOTO/1,0,0", units="inch").warnings == ()
    # units given override a file that says otherwise, with a warning naming its line
    tp = apt("UNITS/MM\nGOTO/1,0,0", units="inch")
    assert tp.units == "inch"
    np.testing.assert_allclose(tp.tip, [[25.4, 0, 0]])
    assert tp.warnings == ("src.apt:1: CL file says mm at line 1; read as inch (--cl-units)",)
    # ... and no warning when the file says the same
    tp = apt("UNITS/MM\nGOTO/1,0,0", units="mm")
    assert (tp.units, tp.warnings) == ("mm", ())
    # no units given: the file's
    tp = apt("UNITS/MM\nGOTO/1,0,0")
    assert tp.units == "mm"
    np.testing.assert_allclose(tp.tip, [[1, 0, 0]])
    # a feed unit anywhere decides, even after the first points
    tp = apt("GOTO/1,0,0\nFEDRAT/IPM,5\nGOTO/2,0,0")
    assert tp.units == "inch"
    np.testing.assert_allclose(tp.tip[:, 0], [25.4, 50.8])


def test_spindle_and_coolant_events():
    tp = apt(
        "SPINDL/ON\nSPINDL/1200\nSPINDL/CCLW\nSPINDL/OFF\nSPINDL/ON\n"
        "COOLNT/ON\nCOOLNT/MIST\nCOOLNT/OFF\nCOOLNT/ON\nCOOLNT/THRU\nCOOLNT/AIR\n"
    )
    spindle = [e.data for e in tp.events if e.kind == "spindle"]
    assert math.isnan(spindle[0]["rpm"]) and spindle[0]["direction"] == "cw"
    assert spindle[1:] == [
        {"rpm": 1200.0, "direction": "cw"},
        {"rpm": 1200.0, "direction": "ccw"},
        {"rpm": 0.0, "direction": "off"},
        {"rpm": 1200.0, "direction": "ccw"},
    ]
    coolant = [e.data["mode"] for e in tp.events if e.kind == "coolant"]
    assert coolant == ["flood", "mist", "off", "mist", "through", "air"]
    assert tp.warnings == ("src.apt:1: spindle turned on with no speed programmed yet",)


def test_tool_records():
    tp = apt(
        "TOOL PATH/OP1,TOOL,EM10\nTLDATA/MILL,10,1,50,0,0\nLOAD/TOOL,3,ADJUST,3\nGOTO/0,0,0\n"
        "SELECT/TOOL,4\nCUTTER/6\nGOTO/1,0,0\nLOADTL/5,LENGTH,80\nGOTO/2,0,0\n"
    )
    events = [(e.kind, e.index, e.data) for e in tp.events]
    assert events == [
        ("operation", 0, {"name": "OP1", "tool_name": "EM10"}),
        ("cutter", 0, {"diameter": 10.0, "corner_radius": 1.0, "length": 50.0}),
        (
            "tool",
            0,
            {
                "number": 3,
                "name": "EM10",
                "diameter": 10.0,
                "corner_radius": 1.0,
                "cutter_length": 50.0,
                "adjust": 3,
            },
        ),
        # CUTTER right after the tool change (no motion between) completes it
        ("tool", 1, {"number": 4, "diameter": 6.0}),
        ("cutter", 1, {"diameter": 6.0}),
        ("tool", 2, {"number": 5, "length": 80.0}),
    ]
    assert tp.warnings == ()


def test_events_text_records():
    tp = apt("PARTNO  BRACKET 12/B\nPPRINT/ROUGHING, 2 MM\nINSERT M08 (x,y)\nGOHOME\nEND\nFINI\n")
    assert [(e.kind, e.data) for e in tp.events] == [
        ("partno", {"text": "BRACKET 12/B"}),
        ("comment", {"text": "ROUGHING, 2 MM"}),
        ("insert", {"text": "M08 (x,y)"}),
        ("home", {}),
    ]
    assert tp.warnings == ()


def test_text_after_fini_warns():
    tp = apt("GOTO/1,2,3\nFINI\n\nGOTO/9,9,9\n$$ x\n")
    assert len(tp) == 1
    assert tp.warnings == ("src.apt:4: 2 non-blank line(s) after FINI ignored",)


def test_nx_listing_lines_and_paint_are_skipped():
    text = (
        "\nInformation listing created by\tuser\nDate : 18-Dec-2021\n"
        "Current work part : C:\\part.prt\nNode name\thost\n-----------\n=======\n"
        "TOOL PATH/OP,TOOL,T\nPAINT/COLOR,3\nGOTO/1,2,3\nEND-OF-PATH\n"
        "Tool Path Listing has 4 lines."
    )
    tp = apt(text)
    assert len(tp) == 1
    assert [e.kind for e in tp.events] == ["operation"]
    assert tp.warnings == ()


# -- CIRCLE ------------------------------------------------------------------------------------


def arc_check(tp, line, centre, normal, radius, sense, tol=0.01):
    """Points of the arc on line ``line``: on the circle, turning about ``sense * normal``."""
    idx = np.flatnonzero(tp.line == line)
    pts = np.vstack([tp.tip[idx[0] - 1], tp.tip[idx]])
    rel = pts - centre
    normal = np.asarray(normal, dtype=float)
    assert np.abs(rel @ normal).max() < 1e-9
    np.testing.assert_allclose(np.linalg.norm(rel, axis=1), radius, atol=1e-9)
    turn = np.cross(rel[:-1], rel[1:]) @ (sense * normal)
    assert np.all(turn > 0)
    cosine = np.sum(rel[:-1] * rel[1:], axis=1) / radius**2
    step = np.arccos(np.clip(cosine, -1, 1))
    assert np.all(radius * (1 - np.cos(step / 2)) <= tol + 1e-12)
    return float(step.sum())


@pytest.mark.parametrize(
    ("normal", "end", "sweep"),
    [
        ((0, 0, 1), (0, 10, 0), math.pi / 2),  # counter-clockwise quarter
        ((0, 0, -1), (0, 10, 0), 3 * math.pi / 2),  # clockwise three quarters
        ((0, 0, 1), (10, 0, 0), 2 * math.pi),  # full circle
        ((0, 0, -1), (10, 0, 0), 2 * math.pi),
        ((0, 0, 1), (-10, 0, 0), math.pi),
    ],
)
def test_circle_apt_right_hand_rule(normal, end, sweep):
    i, j, k = normal
    goto_end = f"GOTO/{end[0]},{end[1]},{end[2]}"
    text = f"FEDRAT/200\nGOTO/10,0,0\nCIRCLE/0,0,0,{i},{j},{k},10,0.01\n{goto_end}\n"
    tp = apt(text, chord_tolerance=0.01)
    assert arc_check(tp, 3, np.zeros(3), normal, 10.0, +1) == pytest.approx(sweep)
    idx = np.flatnonzero(tp.line == 3)
    np.testing.assert_array_equal(tp.tip[idx[-1]], end)
    assert len(idx) == math.ceil(sweep / max_arc_step(10.0, 0.01))
    assert np.all(tp.motion[idx] == Motion.FEED)
    np.testing.assert_allclose(tp.feed[idx], 200.0)
    assert len(tp) == 1 + len(idx)
    assert tp.warnings == (sense_note(3),)


def test_circle_nx_turns_clockwise_about_axis():
    text = "TOOL PATH/OP,TOOL,T\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,-1,10\nGOTO/0,10,0\n"
    tp = apt(text)
    assert arc_check(tp, 3, np.zeros(3), (0, 0, -1), 10.0, -1) == pytest.approx(math.pi / 2)


def test_circle_chord_tolerance_and_tilted_plane():
    n = np.array([1.0, 1.0, 1.0]) / math.sqrt(3)
    u = np.array([1.0, -1.0, 0.0]) / math.sqrt(2)
    centre = np.array([5.0, 6.0, 7.0])
    start = centre + 20 * u
    end = centre + 20 * np.cross(n, u)  # a quarter turn counter-clockwise about n

    def csv(values):
        return ",".join(repr(float(v)) for v in values)

    text = f"GOTO/{csv(start)}\nCIRCLE/{csv(centre)},{csv(n)},20\nGOTO/{csv(end)}\n"
    for tol in (0.1, 0.01, 0.001):
        tp = apt(text, chord_tolerance=tol)
        assert arc_check(tp, 2, centre, n, 20.0, +1, tol=tol) == pytest.approx(math.pi / 2)


def test_circle_keeps_tool_axis_and_helix():
    tp = apt("GOTO/10,0,5,0,0.6,0.8\nCIRCLE/0,0,0,0,0,1,10\nGOTO/-10,0,0\n")
    idx = np.flatnonzero(tp.line == 2)
    np.testing.assert_allclose(tp.axis[idx], np.broadcast_to([0, 0.6, 0.8], (idx.size, 3)))
    z = tp.tip[idx, 2]
    assert np.all(np.diff(z) < 0) and z[-1] == 0.0
    np.testing.assert_allclose(np.hypot(tp.tip[idx, 0], tp.tip[idx, 1]), 10.0)


def test_circle_times_adds_turns():
    tp = apt("GOTO/10,0,3\nCIRCLE/0,0,0,0,0,1,10,0.01,TIMES,3\nGOTO/0,10,0\n")
    idx = np.flatnonzero(tp.line == 2)
    rel = np.vstack([tp.tip[idx[0] - 1], tp.tip[idx]])
    x, y = rel[:, 0], rel[:, 1]
    steps = np.arctan2(x[:-1] * y[1:] - y[:-1] * x[1:], x[:-1] * x[1:] + y[:-1] * y[1:])
    assert np.all(steps > 0)
    assert steps.sum() == pytest.approx(2 * 2 * math.pi + math.pi / 2)
    assert np.all(np.diff(rel[:, 2]) < 0)


def test_circle_radius_mismatch_warns():
    tp = apt("GOTO/10.5,0,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n")
    assert tp.warnings == (
        sense_note(2),
        "src.apt:2: arc end points are 0.5 mm off the CIRCLE radius 10 mm; "
        "the arc is blended between them",
    )


def test_circle_against_incoming_move_warns():
    tp = apt("GOTO/10,10,0\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n")
    assert tp.warnings == (
        sense_note(3),
        "src.apt:3: arc turns against the feed moves around it (start tangent cosine -1.00): "
        f"the other sense, {NX_SENSE}, would continue them; the CIRCLE sense was inferred (no "
        "NX CLSF record in the file): check the CIRCLE direction convention",
    )


def test_circle_may_be_separated_by_paint_and_comments():
    tp = apt("GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\nPAINT/COLOR,3\n$$ x\nGOTO/0,10,0\n")
    assert tp.tip[-1].tolist() == [0, 10, 0]


# -- plain format ------------------------------------------------------------------------------


def test_plain_sample():
    tp = read_cl(DATA / "plain_points.txt")
    np.testing.assert_allclose(tp.tip, [[0, 0, 10], [1.5, 2.5, 3.5], [10, 0, 0], [11, 0, 0]])
    np.testing.assert_allclose(tp.axis, [[0, 0, 1], [0, 0, 1], [0.6, 0, 0.8], [0.6, 0, 0.8]])
    assert list(tp.line) == [2, 3, 5, 6]
    assert np.all(tp.motion == Motion.FEED)
    assert np.isnan(tp.feed).all()
    assert [(e.kind, e.index, e.data["text"]) for e in tp.events] == [
        ("comment", 0, "x y z i j k, millimetres"),
        ("comment", 2, "tilt"),
    ]
    assert tp.units == "mm" and tp.multiaxis and tp.warnings == ()


def test_plain_units_and_modal_axis():
    tp = read_cl_text("1 2 3\n4 5 6 # end\n", format="plain", units="inch")
    assert tp.units == "inch"
    np.testing.assert_allclose(tp.tip, np.array([[1, 2, 3], [4, 5, 6]]) * MM_PER_INCH)
    np.testing.assert_allclose(tp.axis, [[0, 0, 1], [0, 0, 1]])
    assert not tp.multiaxis
    assert [e.index for e in tp.events] == [1]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("1 2 3\n1 2\n", r"p\.txt:2: expected 3 or 6 values \(x y z \[i j k\]\), got 2"),
        ("1 2 3 4\n", r"p\.txt:1: expected 3 or 6 values \(x y z \[i j k\]\), got 4"),
        ("1 x 3\n", r"p\.txt:1: expected a number for the 2nd value, got 'x'"),
        ("1,,3\n", r"p\.txt:1: expected a number for the 2nd value, got ''"),
        ("\n\n1 2 3 0 0 0\n", r"p\.txt:3: expected a unit tool axis, got \(0, 0, 0\)"),
        ("inf 2 3\n", r"p\.txt:1: expected a finite number for the 1st value"),
    ],
)
def test_plain_errors(text, message):
    with pytest.raises(CLDataError, match=message):
        read_cl_text(text, source="p.txt", format="plain")


# -- errors ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        (
            "GOTO/0,0,0\nGOTO/1,2,3,1.2.3,0,1\n",
            2,
            r"src\.apt:2: expected a number for the 4th value of GOTO, got '1\.2\.3'",
        ),
        ("GOTO/1,2,3,4\n", 1, r"src\.apt:1: expected 3 or 6 values in GOTO, got 4"),
        ("GOTO/1,2\n", 1, r"expected 3 or 6 values in GOTO, got 2"),
        ("FROM/1,2,3,4,5\n", 1, r"expected 3 or 6 values in FROM, got 5"),
        ("GOTO/1,,3\n", 1, r"expected a number for the 2nd value of GOTO, got ''"),
        ("\nGOTO/1,2,3,0,0,0\n", 2, r"src\.apt:2: expected a unit tool axis, got \(0, 0, 0\)"),
        ("GOTO/1,2,3,nan,0,1\n", 1, r"expected a unit tool axis, got \(nan, 0, 1\)"),
        ("GOTO/1,2,3,1e999,0,1\n", 1, r"expected a unit tool axis, got \(inf, 0, 1\)"),
        ("GOTO/1e999,2,3\n", 1, r"expected a finite number for the 1st value of GOTO"),
        ("GOTO/1,2,3\nGOTO/4,5,$\n\n", 2, r"src\.apt:2: expected the continuation of this record"),
        ("GOTO/4,5,$", 1, r"got the end of the file"),
        (
            "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\nFEDRAT/10\nGOTO/0,10,0\n",
            2,
            r"src\.apt:2: expected a GOTO after CIRCLE, got 'FEDRAT/10' on line 3",
        ),
        (
            "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\n",
            2,
            r"src\.apt:2: expected a GOTO after CIRCLE, got the end of file",
        ),
        ("CIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n", 1, r"expected a motion before CIRCLE"),
        ("GOTO/1,0,0\nCIRCLE/0,0,0,0,0,1\n", 2, r"expected at least 7 values in CIRCLE, got 6"),
        ("GOTO/1,0,0\nCIRCLE/0,0,0,0,0,1,-2\n", 2, r"expected a positive radius"),
        ("GOTO/1,0,0\nCIRCLE/0,0,0,0,0,0,2\n", 2, r"expected a unit circle axis, got \(0, 0, 0\)"),
        ("GOTO/1,0,0\nCIRCLE/0,0,0,0,0,1,1,TIMES,x\n", 2, r"the 9th value of CIRCLE, got 'x'"),
        ("GOTO/1,0,0\nCIRCLE/0,0,0,0,0,1,1,TIMES,0\n", 2, r"whole number of turns"),
        ("GOTO/0,0,0\nCIRCLE/0,0,0,0,0,1,1\nGOTO/1,0,0\n", 2, r"off the circle axis"),
        ("FEDRAT/-5\n", 1, r"src\.apt:1: expected a positive feed in FEDRAT, got -5"),
        ("FEDRAT/IPM,nan\n", 1, r"expected a positive feed in FEDRAT, got nan"),
        ("FEDRAT/IPM\n", 1, r"expected one feed value in FEDRAT, got 0"),
        ("FEDRAT/1.2.3\n", 1, r"expected a number for the 1st value of FEDRAT, got '1\.2\.3'"),
        ("MSYS/0,0,0,1,0,0\n", 1, r"expected 9 values in MSYS, got 6"),
        ("MSYS/0,0,0,1,0,0,2,0,0\n", 1, r"expected two independent axis vectors in MSYS"),
        ("LOADTL/1.5\n", 1, r"expected a tool number for the 1st value of LOADTL, got '1\.5'"),
        ("LOAD/TOOL,x\n", 1, r"expected a number for the 2nd value of LOAD, got 'x'"),
        ("SPINDL/-100\n", 1, r"expected a spindle speed >= 0"),
        ("CUTTER/-1\n", 1, r"expected tool dimensions >= 0 in CUTTER"),
    ],
)
def test_apt_errors(text, line, message):
    with pytest.raises(CLDataError, match=message) as info:
        apt(text)
    assert info.value.path == "src.apt"
    assert info.value.line == line


def test_error_names_the_file(tmp_path):
    path = tmp_path / "bad.cls"
    path.write_text("GOTO/1,2,3\nGOTO/a,2,3")
    with pytest.raises(CLDataError, match=r"bad\.cls:2: expected a number for the 1st value"):
        read_cl(path)


# -- properties --------------------------------------------------------------------------------

coordinate = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False).map(lambda v: round(v, 6))
unit_axes = (
    st.tuples(*[st.floats(min_value=-1, max_value=1)] * 3)
    .filter(lambda v: 0.1 < math.sqrt(sum(c * c for c in v)))
    .map(lambda v: tuple(c / math.sqrt(sum(x * x for x in v)) for c in v))
)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(coordinate, coordinate, coordinate, unit_axes), min_size=1, max_size=8))
def test_goto_values_round_trip(points):
    lines = ["GOTO/" + ",".join(f"{v:.6f}" for v in (*tip, *axis)) for *tip, axis in points]
    tp = apt("\n".join(lines))
    np.testing.assert_allclose(tp.tip, [p[:3] for p in points], rtol=0, atol=1e-9)
    np.testing.assert_allclose(tp.axis, [p[3] for p in points], rtol=0, atol=1e-5)


@settings(max_examples=60, deadline=None)
@given(
    st.tuples(coordinate, coordinate, coordinate, unit_axes),
    st.sets(st.integers(min_value=0, max_value=4)),
    st.sampled_from(["\n", "\r\n"]),
    st.sampled_from(["", " ", "      "]),
)
def test_continuation_split_at_any_comma(point, cuts, newline, indent):
    values = [f"{v:.6f}" for v in (*point[:3], *point[3])]
    pieces = [values[0]]
    for k, value in enumerate(values[1:]):
        pieces.append(("," + "$" + newline + indent if k in cuts else ",") + value)
    record = "GOTO/" + "".join(pieces)
    split = apt("RAPID\n" + record + newline + "GOTO/0,0,0")
    single = apt("RAPID\nGOTO/" + ",".join(values) + "\nGOTO/0,0,0")
    np.testing.assert_array_equal(split.tip, single.tip)
    np.testing.assert_array_equal(split.axis, single.axis)
    np.testing.assert_array_equal(split.motion, single.motion)
    assert split.line[0] == 2


# -- bulk reading of GOTO runs: the same toolpath as record by record -------------------------


def read_both(text, monkeypatch, **kwargs):
    """The toolpath (or error) of ``text`` read with and without the bulk GOTO reader."""
    out = []
    for least in (1, 10**9):  # every run in bulk; none
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", least)
        try:
            out.append(apt(text, **kwargs))
        except CLDataError as exc:
            out.append((type(exc), str(exc), exc.line))
    return out


def assert_same_toolpath(bulk, single):
    if isinstance(single, tuple) or isinstance(bulk, tuple):
        assert bulk == single
        return
    for name in ("tip", "axis", "feed", "motion", "line"):
        a, b = getattr(bulk, name), getattr(single, name)
        assert a.dtype == b.dtype and a.shape == b.shape, name
        # bit for bit, signs of zeros and NaNs included
        assert a.tobytes() == b.tobytes(), name
    assert bulk.events == single.events
    assert bulk.warnings == single.warnings
    assert (bulk.units, bulk.multiaxis) == (single.units, single.multiaxis)


def test_bulk_reader_reads_runs_in_bulk(monkeypatch):
    lines = [f"GOTO/{k}.5,-{k}.25,{k % 7},0,0.6,0.8" for k in range(100)]
    text = "UNITS/INCHES\nMSYS/1,2,3,0,1,0,-1,0,0\nFEDRAT/IPM,10\n" + "\n".join(lines) + "\n"
    scan = apt_module.scan_text(text, "src.apt")
    runs = [r for r in scan.records if isinstance(r, apt_module.GotoRun)]
    assert [(r.line, len(r)) for r in runs] == [(4, 100)]
    assert runs[0].records()[99].text == lines[99]
    bulk, single = read_both(text, monkeypatch)
    assert_same_toolpath(bulk, single)
    assert len(bulk) == 100 and list(bulk.line) == list(range(4, 104))


@pytest.mark.parametrize(
    "text",
    [
        # a run after RAPID, after CIRCLE (the first GOTO ends the arc), and continuing a record
        "FEDRAT/100\nRAPID\n{run}",
        "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\n{run}",
        "GOTO/1,2,$\n{run}",
        "FEDRAT/$\n{run}",
        # values that need a message: the run is read record by record, messages unchanged
        "{run}GOTO/1,2,3,0,0,2\n{run}",
        "{run}GOTO/1,2,3,0,0,0\n{run}",
        "{run}GOTO/1e999,2,3,0,0,1\n{run}",
        "{run}GOTO/1,2,3,nan,0,1\n{run}",
        "{run}GOTO/1,2,3,1.2.3,0,1\n{run}",
        "{run}GOTO/1_0,2,3,0,0,1\n{run}",
        "{run}GOTO/١,2,3,0,0,1\n{run}",
        "{run}GOTO/1,2,3,0,0,1,GOTO/1\n{run}",
        "{run}GOTO/1,2,3 # 4\n{run}",
        # mixed value counts, trailing comments, continuations inside a block of GOTO lines
        "{run}{short}{run}",
        "{run}GOTO/1,2,3 $$ 4,5,6\n{run}GOTO/1,2,$\n3\n{run}",
        "{run}GOTO/1,2,3$ $$ x\nGOTO/4,5,6\n{run}",
        # FINI inside, before and after runs
        "{run}FINI\n{run}",
        "{run}GOTO/1,2,3\nFINI\n\n$$ x\n{run}",
        "FINI\n{run}",
        # other line ends and no final newline
        "RAPID\r\n{run_crlf}GOTO/4,5,$\r\n6\r\nFINI",
        "{run}".rstrip("\n"),
        # a file that is only a run, a run between events, MSYS and units changes
        "{run}",
        "PARTNO X\nLOADTL/1\n{run}COOLNT/ON\n{short}{run}MSYS/1,0,0,0,1,0,-1,0,0\n{run}"
        "UNITS/INCHES\n{run}END\n",
        # an arc starting at the end of a run, and an arc whose end starts a run
        "FEDRAT/50\n{run}CIRCLE/0,0,0,0,0,1,5\n{run}",
    ],
)
def test_bulk_reader_equals_record_by_record(text, monkeypatch):
    run = "".join(f"GOTO/{k * 0.1:.4f},{-k:.3f},{k % 3},0.6,0,0.8\n" for k in range(1, 40))
    short = "".join(f"GOTO/{k},{k},{k}\n" for k in range(40))
    text = text.format(run=run, short=short, run_crlf=run.replace("\n", "\r\n"))
    bulk, single = read_both(text, monkeypatch, chord_tolerance=0.01)
    assert_same_toolpath(bulk, single)


_number_text = st.one_of(
    st.floats(-1e5, 1e5, allow_nan=False).map(lambda v: f"{v:.4f}"),
    st.floats(-1.0, 1.0).map(lambda v: f"{v:.7f}"),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.integers(-1000, 1000).map(str),
    st.sampled_from(["-0", "+.5", "5.", "1e3", "-0.0", " 2 ", "0", "1E-2", "nan", "1e999", ""]),
)
_goto_line = st.one_of(
    st.lists(_number_text, min_size=3, max_size=3).map(lambda v: "GOTO/" + ",".join(v)),
    st.tuples(
        st.lists(_number_text, min_size=3, max_size=3),
        st.sampled_from([(0.6, 0.0, 0.8), (0.0, 0.0, 1.0), (-0.0, -0.0, -1.0), (1.0, 0.0, 0.0)]),
    ).map(lambda v: "GOTO/" + ",".join([*v[0], *(f"{c:.6f}" for c in v[1])])),
    st.sampled_from(["GOTO/1,2,3 $$ c", "GOTO/1,2,$", "3", "GOTO/1,2,3,0,0,0", "GOTO/1,2"]),
)
_other_line = st.sampled_from(
    [
        "RAPID",
        "FEDRAT/200",
        "FEDRAT/IPM,5",
        "$$ comment",
        "",
        "UNITS/INCHES",
        "MSYS/1,2,3,0,1,0,-1,0,0",
        "MULTAX/ON",
        "PAINT/COLOR,3",
        "CIRCLE/0,0,0,0,0,1,10",
        "FINI",
        "goto/1,2,3",
        " GOTO/1,2,3",
    ]
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    st.lists(
        st.one_of(st.lists(_goto_line, min_size=1, max_size=6), _other_line.map(lambda x: [x])),
        max_size=12,
    ),
    st.sampled_from(["\n", "\r\n", "\r"]),
    st.booleans(),
)
def test_bulk_reader_equals_record_by_record_random(groups, newline, final_newline):
    lines = [line for group in groups for line in group]
    text = newline.join(lines) + (newline if final_newline else "")
    with pytest.MonkeyPatch.context() as monkeypatch:
        bulk, single = read_both(text, monkeypatch, chord_tolerance=0.05)
    assert_same_toolpath(bulk, single)


def test_arc_too_large_to_interpolate_is_a_clear_error() -> None:
    """An arc whose radius needs more points than any machine could cut names its line."""
    from urdfpost.errors import CLDataError
    from urdfpost.readers import read_cl_text

    # the end point as far as a length may be (1e9 mm), five turns: 11 million points
    text = "GOTO/0,0,0\nGOTO/0,1,0\nCIRCLE/0,0,0,0,0,1,10,TIMES,5\nGOTO/0,1e9,0\n"
    with pytest.raises(CLDataError, match=r":3: expected an arc a machine can cut"):
        read_cl_text(text, source="huge.apt")
    # further, the end point itself is refused (issue 22)
    text = "GOTO/0,0,0\nGOTO/0,1,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,1.3e154,0\n"
    with pytest.raises(CLDataError, match=r":4: GOTO: y 1\.3e154 mm is beyond the largest length"):
        read_cl_text(text, source="huge.apt")


def test_bulk_reader_long_blocks_in_pieces(monkeypatch):
    """Blocks longer than a piece are read in several runs, the same points."""
    monkeypatch.setattr(apt_module, "_BULK_PIECE", 200)
    monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 4)
    lines = [f"GOTO/{k}.25,{-k}.5,{k % 5},0,0.6,0.8" for k in range(500)]
    text = "FEDRAT/100\n" + "\n".join(lines) + "\nGOTO/1,2,3 $$ x\n" + "\n".join(lines)
    scan = apt_module.scan_text(text, "src.apt")
    runs = [r for r in scan.records if isinstance(r, apt_module.GotoRun)]
    assert len(runs) > 4
    assert sum(len(r) for r in runs) > 900
    bulk, single = read_both(text, monkeypatch)
    assert_same_toolpath(bulk, single)


def test_scan_records_stops_at_fini():
    scan = apt_module.scan_records(["GOTO/1,2,3", "FINI", "", "GOTO/4,5,6", "$$ x"], "src.apt")
    assert [r.word for r in scan.records] == ["GOTO", "FINI"]
    assert scan.after_fini == [4, 5]


# -- free text and continuations (the hostile test run) ---------------------------------------

PRICE = "UNITS/MM\nMULTAX/ON\nFEDRAT/MMPM,1000\nGOTO/0,0,10\nPPRINT PRICE IN US$\n{gotos}FINI\n"


@pytest.mark.parametrize("gotos", [1, 40])  # record by record; a run long enough for bulk
def test_a_dollar_in_pprint_text_is_text(gotos, monkeypatch, tmp_path):
    """``PPRINT PRICE IN US$`` ends with a ``$`` that is text: the GOTO after it is a point,
    not the comment's continuation, read whole, streamed, with and without bulk runs."""
    text = PRICE.format(gotos="".join(f"GOTO/{k + 1},0,10\n" for k in range(gotos)))
    for tp in read_both(text, monkeypatch):
        assert len(tp) == gotos + 1
        assert [e.data["text"] for e in tp.events if e.kind == "comment"] == ["PRICE IN US$"]
    path = tmp_path / "price.apt"
    path.write_text(text)
    from urdfpost.readers import read_cl_chunks

    streamed = list(read_cl_chunks(path, max_points=7))
    assert sum(len(tp) for tp in streamed) == gotos + 1


def test_double_dollar_in_pprint_is_text():
    tp = apt("PPRINT COST $$ 5\nGOTO/1,0,0")
    assert [e.data["text"] for e in tp.events if e.kind == "comment"] == ["COST $$ 5"]


@pytest.mark.parametrize("gotos", [1, 40])
def test_a_continuation_never_swallows_a_motion_record(gotos, monkeypatch):
    """A record whose last line ends with ``$`` followed by a GOTO: an error at the record
    (never the GOTO read as part of it and lost)."""
    text = "UNITS/MM\nFEDRAT/MMPM,$\n" + "".join(f"GOTO/{k},0,10\n" for k in range(gotos))
    for got in read_both(text, monkeypatch):
        assert isinstance(got, tuple), got
        kind, message, line = got
        assert kind is CLDataError
        assert line == 2
        assert "got the motion record at line 3" in message


# -- encodings: byte-order marks and NUL bytes -------------------------------------------------

ENCODED = "PARTNO BRACKET\nUNITS/INCHES\nMULTAX/ON\nFEDRAT/IPM,10\nGOTO/1,0,1,0,0,1\nGOTO/2,0,1\n"


def read_whole_and_streamed(path: Path) -> list[object]:
    """read_cl and read_cl_chunks (small pieces) of ``path``: toolpaths, or the error."""
    from urdfpost.readers import read_cl_chunks

    out: list[object] = []
    for read in (lambda: [read_cl(path)], lambda: list(read_cl_chunks(path, max_points=1))):
        try:
            out.append(read())
        except CLDataError as exc:
            out.append((exc.line, str(exc)))
    return out


@pytest.mark.parametrize(
    ("mark", "codec"),
    [
        (b"\xef\xbb\xbf", "utf-8"),
        (b"\xff\xfe", "utf-16-le"),
        (b"\xfe\xff", "utf-16-be"),
        (b"\xff\xfe\x00\x00", "utf-32-le"),
    ],
)
@pytest.mark.parametrize("newline", ["\n", "\r\n"])
def test_a_byte_order_mark_is_decoded(tmp_path, mark, codec, newline):
    """A byte-order mark before ``PARTNO`` or ``UNITS/INCHES`` is not part of the record: the
    name is the name, and inch values are read as inches, whole and streamed."""
    path = tmp_path / "marked.apt"
    path.write_bytes(mark + ENCODED.replace("\n", newline).encode(codec))
    for got in read_whole_and_streamed(path):
        assert isinstance(got, list), got
        assert all(tp.units == "inch" for tp in got)
        np.testing.assert_allclose(np.concatenate([tp.tip for tp in got])[:, 0], [25.4, 50.8])
        names = [e.data["text"] for e in got[0].events if e.kind == "partno"]
        assert names == ["BRACKET"]
        assert not any(tp.warnings for tp in got)


@pytest.mark.parametrize(
    ("data", "line"),
    [
        (ENCODED.encode("utf-16-le"), 1),  # UTF-16 saved without a mark
        (ENCODED.encode() + b"GOTO/3,0\x001\n", 7),
        (ENCODED.replace("\n", "\r").encode() + b"\x00\x01\x02", 7),
    ],
)
def test_a_nul_byte_is_an_encoding_error_at_its_line(tmp_path, data, line):
    path = tmp_path / "wide.apt"
    path.write_bytes(data)
    for got in read_whole_and_streamed(path):
        assert isinstance(got, tuple), got
        assert got[0] == line
        assert "NUL byte: expected text in ASCII or UTF-8" in got[1]


@pytest.mark.parametrize("rule", ["--------", "========", "  ----------  "])
def test_a_rule_line_is_no_evidence_of_nx(rule):
    """A bare separator line in an APT file is skipped and does not make the file NX CLSF:
    the CIRCLE keeps the APT sense (a 90-degree arc stays one)."""
    arc = "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n"
    plain, ruled = apt(arc), apt(rule + "\n" + arc)
    np.testing.assert_array_equal(plain.tip, ruled.tip)
    angles = np.degrees(np.arctan2(ruled.tip[:, 1], ruled.tip[:, 0]))
    assert angles[-1] == pytest.approx(90.0)
    assert np.all(np.diff(angles) > 0)  # counter-clockwise, the short way


# -- junk: files that are not CL data, records of megabytes (issue 22) -------------------------


def printable_junk(size: int, seed: int) -> str:
    """``size`` characters of random printable ASCII (with its line breaks)."""
    import random
    import string

    rng = random.Random(seed)
    return "".join(rng.choice(string.printable) for _ in range(size))


@pytest.mark.parametrize("seed", [0, 1])
def test_random_text_is_not_a_cl_file(tmp_path, seed):
    """100 KB of printable random text named .apt: refused at its first unknown record,
    whole and streamed, with the count of unknown records."""
    path = tmp_path / "junk.apt"
    path.write_text(printable_junk(100_000, seed), newline="")
    got = read_whole_and_streamed(path)
    assert got[0] == got[1]
    assert isinstance(got[0], tuple), got[0]
    line, message = got[0]
    found = re.fullmatch(
        rf"{re.escape(str(path))}:(\d+): not a CL file: (?:no motion record, and )?(\d+) of "
        r"(\d+) records are unknown, the first at line (\d+); expected APT/CLSF records such as "
        r"GOTO, FEDRAT, CIRCLE",
        message,
    )
    assert found, message
    assert int(found[1]) == int(found[4]) == line
    assert int(found[2]) > 0.5 * int(found[3]) > 10


@pytest.mark.parametrize(
    ("unknown", "gotos", "refused"),
    [
        (20, 1, False),  # few unknown records: carried, whatever their share
        (21, 20, True),  # more than 20, and more than half
        (21, 21, False),  # exactly half: CL data with many odd words
        (1, 0, True),  # no motion, and mostly unknown
        (2, 0, True),  # (after a $$ comment)
    ],
)
def test_unknown_records_refused_when_they_dominate(tmp_path, unknown, gotos, refused):
    lines = ["$$ header"] if gotos == 0 and unknown == 2 else []
    lines += [f"FROB/{k}" for k in range(unknown)] + [f"GOTO/{k},0,0" for k in range(gotos)]
    path = tmp_path / "odd.apt"
    path.write_text("\n".join(lines) + "\n")
    for got in read_whole_and_streamed(path):
        if refused:
            assert isinstance(got, tuple), got
            first = 2 if lines[0] == "$$ header" else 1
            assert got[0] == first
            assert f"of {len(lines)} records are unknown, the first at line {first};" in got[1]
        else:
            assert isinstance(got, list), got
            assert sum(len(tp.warnings) for tp in got) == unknown


def test_no_motion_and_few_unknown_records_is_read():
    tp = apt("PARTNO X\n$$ nothing to cut yet\nFROB/1\n")
    assert len(tp) == 0 and [e.kind for e in tp.events] == ["partno", "comment", "unknown"]


@pytest.mark.parametrize(
    "path",
    [*sorted((Path(__file__).parent / "data" / "cl").iterdir()), PROJECT2, BALLMILL],
    ids=lambda p: p.name,
)
def test_real_files_are_not_refused(path):
    """Every CL file of tests/data and ../shared is CL data: none is refused as junk."""
    for got in read_whole_and_streamed(real_file(path)):
        assert isinstance(got, list), got


def test_a_junk_line_of_megabytes_is_quoted_and_carried_short(tmp_path):
    """A 5 MB junk line between two GOTOs: the warning quotes 80 characters and says how
    many more there are; the comment carried into the program keeps 200 (said in the
    warning)."""
    junk = "Q" + "x" * 5_000_000
    path = tmp_path / "long.apt"
    path.write_text(f"GOTO/0,0,0\n{junk}\nGOTO/1,0,0\n")
    for got in read_whole_and_streamed(path):
        assert isinstance(got, list), got
        warnings = [w for tp in got for w in tp.warnings]
        assert warnings == [
            f"{path}:2: unknown record '{junk[:80]}... ({len(junk) - 80} more characters)' "
            f"carried as a comment, shortened to its first 200 characters "
            f"({len(junk) - 200} more dropped)"
        ]
        (event,) = [e for tp in got for e in tp.events]
        assert event.kind == "unknown" and event.data == {"text": junk[:200]}
        assert sum(len(tp) for tp in got) == 2


@pytest.mark.parametrize(
    ("record", "kind", "name"),
    [
        ("$$ " + "c" * 300, "comment", "$$ comment"),
        ("PPRINT " + "c" * 300, "comment", "PPRINT"),
        ("PARTNO " + "c" * 300, "partno", "PARTNO"),
    ],
)
def test_a_long_comment_is_carried_short(record, kind, name):
    tp = apt(f"{record}\nGOTO/0,0,0\n")
    assert [(e.kind, e.data["text"]) for e in tp.events] == [(kind, "c" * 200)]
    assert tp.warnings == (
        f"src.apt:1: {name} carried as a comment, shortened to its first 200 characters "
        "(100 more dropped)",
    )


def test_a_long_insert_is_verbatim():
    tp = apt("INSERT " + "G1 X1 " * 100 + "\nGOTO/0,0,0\n")
    assert len(tp.events[0].data["text"]) == 599 and tp.warnings == ()


def test_a_comment_of_200_characters_is_whole():
    tp = apt("$$ " + "c" * 200 + "\nGOTO/0,0,0\n")
    assert tp.events[0].data["text"] == "c" * 200 and tp.warnings == ()


@pytest.mark.parametrize(
    "text",
    [
        "GOTO/1,2," + "9x" * 5000 + "\n",
        "GOTO/1,0,0\nCIRCLE/0,0,0,0,0,1,10\n" + "Z" * 10_000 + "\n",
        "GOTO/1,0,0\nCIRCLE/0,0,0,0,0,1," + "-" * 10_000 + "\n",
        "LOADTL/" + "7" * 5000 + "x\n",
        "1 2 " + "3" * 5000 + "x\n",
    ],
)
def test_an_error_quotes_a_long_value_short(text):
    with pytest.raises(CLDataError) as info:
        read_cl_text(text, source="src.apt")
    assert len(str(info.value)) < 300
    assert re.search(r"\.\.\. \(\d+ more characters\)", str(info.value))


# -- the CIRCLE sense: inferred, said once, checked against the tangents (issue 22) -----------

#: A 90-degree arc counter-clockwise about +Z from (10,0) to (0,10), between a feed move
#: along +Y into it and one along -X out of it: tangent to both. NX CLSF writes it with the
#: circle axis -Z (it turns clockwise about its axis), APT with +Z.
TANGENT_ARC = "FEDRAT/100\nGOTO/10,-10,0\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,{k},10\nGOTO/0,10,0\n"
TANGENT_ARC += "GOTO/-10,10,0\n"


def quarter_arc_points(tp, line: int) -> np.ndarray:
    """The points of the arc of CIRCLE line ``line``, with the point before it."""
    idx = np.flatnonzero(tp.line == line)
    return tp.tip[idx[0] - 1 : idx[-1] + 1]


@pytest.mark.parametrize(
    ("head", "k", "reason"),
    [
        ("", "1", ""),  # APT: counter-clockwise about +Z
        (
            "TOOL PATH/OP,TOOL,T\n",
            "-1",
            "the NX record TOOL PATH at line 1",
        ),  # NX: clockwise about -Z
    ],
)
def test_a_tangent_arc_in_each_convention(head, k, reason):
    """Each convention reads its own arc as the quarter turn between the two lines; the sense
    is said once (the first CIRCLE), and the tangents agree: no other warning."""
    line = 4 + bool(head)
    tp = apt(head + TANGENT_ARC.format(k=k))
    assert tp.warnings == (sense_note(line, reason),)
    arc = quarter_arc_points(tp, line)
    angles = np.unwrap(np.arctan2(arc[:, 1], arc[:, 0]))
    assert np.all(np.diff(angles) > 0) and angles[-1] - angles[0] == pytest.approx(math.pi / 2)


@pytest.mark.parametrize(
    ("head", "k", "reason", "other"),
    [
        ("", "-1", "no NX CLSF record in the file", NX_SENSE),  # NX data read as APT
        ("TOOL PATH/OP,TOOL,T\n", "1", "the NX record TOOL PATH at line 1", APT_SENSE),
    ],
)
def test_an_arc_against_its_tangents_warns(tmp_path, head, k, reason, other):
    """The arc of the other convention: read in the inferred sense it is the long way round,
    backwards at both lines; the warning names the CIRCLE line and both cosines, whole and
    streamed (the end is only known at the move after the arc)."""
    line = 4 + bool(head)
    path = tmp_path / "against.apt"
    path.write_text(head + TANGENT_ARC.format(k=k) + "GOTO/-20,10,0\n")
    for got in read_whole_and_streamed(path):
        assert isinstance(got, list), got
        warnings = [w for tp in got for w in tp.warnings]
        assert warnings == [
            sense_note(line, "" if not head else reason, str(path)),
            f"{path}:{line}: arc turns against the feed moves around it (start tangent cosine "
            f"-1.00, end tangent cosine -1.00): the other sense, {other}, would continue them; "
            f"the CIRCLE sense was inferred ({reason}): check the CIRCLE direction convention",
        ]
    arc = quarter_arc_points(read_cl(path), line)  # the sense inferred is kept: 270 degrees
    angles = np.unwrap(np.arctan2(arc[:, 1], arc[:, 0]))
    assert abs(angles[-1] - angles[0]) == pytest.approx(3 * math.pi / 2)


@pytest.mark.parametrize(
    ("text", "warned"),
    [
        # plunge into the arc, retract out of it: square to it, no evidence
        ("GOTO/10,0,5\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,-1,10\nGOTO/0,10,0\nGOTO/0,10,5\n", False),
        # against at the start only, the end move square to the arc
        ("GOTO/10,-10,0\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,-1,10\nGOTO/0,10,0\nGOTO/0,10,5\n", True),
        # against at the end only, no move before the arc but the first point
        ("GOTO/10,0,0\nCIRCLE/0,0,0,0,0,-1,10\nGOTO/0,10,0\nGOTO/-10,10,0\n", True),
        # along at the start, against at the end: a corner, not a question of the sense
        ("GOTO/10,-10,0\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\nGOTO/10,10,0\n", False),
        # a rapid out of the arc is no evidence
        ("GOTO/10,0,0\nCIRCLE/0,0,0,0,0,-1,10\nGOTO/0,10,0\nRAPID\nGOTO/-10,10,0\n", False),
        # arc after arc: the second has no linear move into it, the first none out of it
        (
            "GOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\nCIRCLE/0,0,0,0,0,1,10\n"
            "GOTO/-10,0,0\n",
            False,
        ),
    ],
)
def test_the_tangent_check_needs_evidence(text, warned):
    tp = apt("FEDRAT/100\n" + text)
    assert tp.warnings[0].startswith("src.apt:")
    assert "CIRCLE sense inferred" in tp.warnings[0]
    assert any("arc turns against" in w for w in tp.warnings[1:]) is warned
    assert len(tp.warnings) == 1 + warned


def test_a_file_without_arcs_gets_no_sense_warning():
    assert apt("GOTO/0,0,0\nGOTO/1,0,0\n").warnings == ()


# -- LOADTL ADJUST (issue 22) --------------------------------------------------------------------


@pytest.mark.parametrize(
    ("record", "data"),
    [
        ("LOADTL/3,ADJUST,7", {"number": 3, "adjust": 7}),
        ("LOADTL / 3, adjust, 7", {"number": 3, "adjust": 7}),
        ("LOAD/TOOL,3,ADJUST,7", {"number": 3, "adjust": 7}),
        ("SELECT/TOOL,3,ADJUST,0", {"number": 3, "adjust": 0}),
        ("LOADTL/3,LENGTH,50,ADJUST,7.0", {"number": 3, "length": 50.0, "adjust": 7}),
        ("LOADTL/3,ADJUST,7,LENGTH,50", {"number": 3, "adjust": 7, "length": 50.0}),
        ("LOADTL/3", {"number": 3}),
    ],
)
def test_loadtl_adjust_is_the_length_offset_register(record, data):
    tp = apt(f"{record}\nGOTO/0,0,0\n")
    (event,) = tp.events
    assert event.kind == "tool" and event.data == data
    assert isinstance(event.data.get("adjust", 0), int)
    assert tp.warnings == ()


@pytest.mark.parametrize(
    ("record", "message"),
    [
        ("LOADTL/3,ADJUST", "the 3rd value of LOADTL after ADJUST, got nothing"),
        ("LOADTL/3,ADJUST,", "the 3rd value of LOADTL after ADJUST, got nothing"),
        ("LOADTL/3,ADJUST,-1", "got '-1'"),
        ("LOADTL/3,ADJUST,2.5", "got '2.5'"),
        ("LOADTL/3,ADJUST,nan", "got 'nan'"),
        ("LOADTL/3,ADJUST,H7", "got 'H7'"),
        ("LOAD/TOOL,3,ADJUST,X", "the 4th value of LOAD after ADJUST, got 'X'"),
        ("LOADTL/3,ADJUST,1,ADJUST,2", "expected one ADJUST in LOADTL, got two"),
    ],
)
def test_a_bad_adjust_is_an_error_at_the_record(record, message):
    with pytest.raises(CLDataError, match=r"^src\.apt:2: ") as info:
        apt(f"GOTO/0,0,0\n{record}\nGOTO/1,0,0\n")
    assert message in str(info.value)
    if "one ADJUST" not in message:
        assert "expected a length-offset register (a whole number >= 0)" in str(info.value)


@pytest.mark.parametrize(
    ("record", "ignored"),
    [("LOADTL/3,IN", "IN"), ("LOADTL/3,ADJUST,7,MILL,2", "MILL,2"), ("LOADTL/1,1,1", "1,1")],
)
def test_other_loadtl_words_are_warned_not_dropped(record, ignored):
    tp = apt(f"{record}\nGOTO/0,0,0\n")
    assert tp.warnings == (
        f"src.apt:1: LOADTL: '{ignored}' after the tool number not understood; ignored "
        "(LENGTH and ADJUST are read)",
    )
    assert [e.kind for e in tp.events] == ["tool"]


# -- GODLTA: a motion record, never carried as a comment (found with the fuzzing, issue 22) ------


def test_godlta_moves_by_a_delta_or_along_the_tool_axis():
    tp = apt(
        "FEDRAT/100\nGOTO/1,2,3\nGODLTA/0,0,5\nGODLTA/-2\nGOTO/1,2,3,0.6,0,0.8\nGODLTA/10\n"
        "RAPID\nGODLTA/1,1,1\n"
    )
    np.testing.assert_allclose(
        tp.tip, [[1, 2, 3], [1, 2, 8], [1, 2, 6], [1, 2, 3], [7, 2, 11], [8, 3, 12]]
    )
    assert list(tp.line) == [2, 3, 4, 5, 6, 8]
    assert list(tp.motion) == [Motion.FEED] * 5 + [Motion.RAPID]
    np.testing.assert_allclose(tp.feed[:5], 100.0)
    np.testing.assert_allclose(tp.axis[-1], [0.6, 0, 0.8])
    assert tp.events == () and tp.warnings == ()


def test_godlta_in_inch_and_in_a_second_mcs():
    tp = apt("UNITS/INCHES\nGOTO/1,0,0\nGODLTA/0,0,1\n")
    np.testing.assert_allclose(tp.tip[-1], [25.4, 0, 25.4])
    # the second MCS turned 90 degrees about Z: its +X is the first's +Y
    tp = apt(
        "MSYS/0,0,0,1,0,0,0,1,0\nGOTO/0,0,0\nMSYS/0,0,0,0,1,0,-1,0,0\nGODLTA/1,0,0\n",
    )
    np.testing.assert_allclose(tp.tip[-1], [0, 1, 0], atol=1e-12)


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        ("GODLTA/0,0,1\n", 1, "expected a motion before GODLTA (it moves from there), got none"),
        ("GOTO/0,0,0\nGODLTA/1,2\n", 2, "expected 1 value (a distance along the tool axis) or 3"),
        ("GOTO/0,0,0\nGODLTA\n", 2, "or 3 (dx, dy, dz) in GODLTA, got 0"),
        ("GOTO/0,0,0\nGODLTA/nan\n", 2, "expected a finite number for the 1st value of GODLTA"),
        ("GOTO/0,0,0\nGODLTA/1,x,1\n", 2, "expected a number for the 2nd value of GODLTA"),
        ("GOTO/0,0,0\nGODLTA/0,0,1e300\n", 2, "GODLTA: dz 1e300 mm is beyond the largest"),
        ("GOTO/1,0,0\nCIRCLE/0,0,0,0,0,1,1\nGODLTA/1\n", 2, "expected a GOTO after CIRCLE"),
    ],
)
def test_godlta_errors(text, line, message):
    with pytest.raises(CLDataError, match=rf"^src\.apt:{line}: ") as info:
        apt(text)
    assert message in str(info.value)
