"""The compiled GOTO scan (:mod:`urdfpost.readers._goto_kernel`, issue 21) against the numpy path.

The two must read every APT text to the same toolpath, bit for bit, or fail with the same
error: the numbers of the compiled loop are those of ``float()``; the lines it cannot read
exactly go to ``np.loadtxt`` (odd lines) or to the scanner, record by record. Skipped without
numba (the ``fast`` extra).
"""

from __future__ import annotations

import logging
import math
import re
import sys
from collections.abc import Callable, Iterator
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import SHARED_CL
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import urdfpost.readers.apt as apt_module
from urdfpost.errors import CLDataError
from urdfpost.readers import read_cl, read_cl_chunks, read_cl_text
from urdfpost.readers._stream import line_count
from urdfpost.toolpath import Toolpath

pytest.importorskip("numba")

from urdfpost.readers._goto_kernel import goto_runs, plain_goto_lines

FIELDS = ("tip", "axis", "feed", "motion", "line")
NEVER = 1 << 62  # COMPILED_FROM for the numpy path
PROPERTY = settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


def outcome(read: Callable[[], Toolpath | list[Toolpath]]) -> object:
    """The toolpath(s) as comparable values (arrays as bytes: bit for bit), or the error."""
    try:
        got = read()
    except CLDataError as exc:
        return type(exc), str(exc), exc.line
    pieces = got if isinstance(got, list) else [got]
    return [
        (
            tuple(getattr(p, f).tobytes() for f in FIELDS),
            [(e.index, e.kind, e.line, repr(e.data)) for e in p.events],
            p.warnings,
            p.units,
            p.multiaxis,
        )
        for p in pieces
    ]


def compiled_from(monkeypatch: pytest.MonkeyPatch, size: int) -> None:
    """Read with the compiled loop from ``size`` characters on, numba imported or not."""
    monkeypatch.setattr(apt_module.KERNELS, "start", size)
    monkeypatch.setattr(apt_module.KERNELS, "warm_start", size)


def both_ways(read: Callable[[], Toolpath | list[Toolpath]]) -> tuple[object, object]:
    """``read`` by the numpy path and by the compiled loop."""
    out = []
    for size in (NEVER, 0):
        with pytest.MonkeyPatch.context() as monkeypatch:
            compiled_from(monkeypatch, size)
            out.append(outcome(read))
    return out[0], out[1]


def assert_same_reading(text: str, least: int = 3, piece: int | None = None) -> None:
    """The text read whole by both paths, with runs of ``least`` lines and the bulk reader's
    pieces of ``piece`` characters, gives the same toolpath or error."""
    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", least)
        if piece is not None:
            monkeypatch.setattr(apt_module, "_BULK_PIECE", piece)
        numpy_way, compiled = both_ways(lambda: read_cl_text(text, source="k.apt", format="apt"))
    assert compiled == numpy_way


def kernel(text: str, least: int = 1, piece: int = 1 << 30) -> Iterator[tuple[str, np.ndarray]]:
    """The lines of the kernel's runs with their values (odd lines' as NaN)."""
    data = np.frombuffer(text.encode("ascii", "replace"), dtype=np.uint8)
    runs, values, _, feeds, _, needed, _, _ = goto_runs(data, least, piece, 10**4, 10**4, 10**4)
    assert needed == len(runs)
    for start, end, count, width, _comments, first, first_feed, feed_count in runs.tolist():
        at = set(feeds[first_feed : first_feed + feed_count, 0].tolist())
        lines = [line for line in text[start:end].split("\n") if not line.startswith("FEDRAT/")]
        lines = lines[:count]
        assert not at or max(at) < count
        rows = values[first : first + count * width].reshape(count, width)
        yield from zip(lines, rows, strict=True)


def bits(values: list[float] | np.ndarray) -> bytes:
    return np.asarray(values, dtype=np.float64).tobytes()


# -- numbers: the kernel's values are float()'s ----------------------------------------------

_digits = st.text("0123456789", max_size=24)


@st.composite
def numbers(draw: st.DrawFn) -> str:
    """A number as a CL file may write it: signs, leading zeros, no leading digit, a trailing
    point, exponents, many digits, blanks around it."""
    whole, fraction = draw(_digits), draw(_digits)
    point = draw(st.booleans())
    if not (whole or fraction):
        whole = "0"
    if not whole:
        point = True
    text = draw(st.sampled_from(["", "+", "-"])) + whole + ("." + fraction if point else "")
    if draw(st.integers(0, 9)) == 0:
        text += draw(st.sampled_from(["e", "E"])) + draw(st.sampled_from(["", "-", "+"]))
        text += str(draw(st.integers(0, 40)))
    blank = st.sampled_from(["", "", " ", "  ", "\t"])
    return draw(blank) + text + draw(blank)


@st.composite
def fixed(draw: st.DrawFn) -> str:
    """A number as CAM systems write them: a fixed number of decimals."""
    value = draw(st.floats(-1e5, 1e5, allow_nan=False))
    return f"{value:.{draw(st.integers(0, 9))}f}"


@PROPERTY
@given(st.lists(st.lists(st.one_of(numbers(), fixed()), min_size=3, max_size=3), min_size=1))
def test_kernel_values_are_float_of_the_text(rows):
    lines = ["GOTO/" + ",".join(row) for row in rows]
    text = "\n".join(lines) + "\n"
    got = list(kernel(text))
    assert [line for line, _ in got] == lines  # every line in the run
    for (line, values), row in zip(got, rows, strict=True):
        plain = [float(v) for v in row]
        if np.isnan(values).any():  # an odd line: left to np.loadtxt
            assert all(np.isnan(values))
            assert any(re.search(r"[eE]", v) or len(re.sub(r"\D", "", v)) > 15 for v in row), line
        else:
            assert bits(values) == bits(plain), line


@PROPERTY
@given(st.lists(st.tuples(fixed(), fixed(), fixed()), min_size=1, max_size=20))
def test_kernel_reads_fixed_decimals_itself(rows):
    """Numbers as CAM systems write them are read by the loop (none left odd)."""
    text = "".join(f"GOTO/{x},{y},{z}\n" for x, y, z in rows)
    got = list(kernel(text))
    assert len(got) == len(rows)
    for (_, values), row in zip(got, rows, strict=True):
        assert bits(values) == bits([float(v) for v in row])


@pytest.mark.parametrize(
    ("value", "odd"),
    [
        ("0.1", False),
        ("-0", False),
        ("-0.000", False),
        ("+.5", False),
        ("5.", False),
        ("007.250", False),
        ("9007199254740992", False),  # 2**53: exact
        ("9007199254740993", True),  # 2**53 + 1: np.loadtxt rounds it
        ("0.30000000000000004", True),  # 17 digits, m beyond 2**53
        ("0.3000000000000004", False),  # 16 digits, m below 2**53
        ("123456789012345678", True),  # beyond 2**53
        ("1.0000000000000000000001", True),  # too many digits
        ("0.0000000000000000000001", True),  # too many digits (leading zeros count)
        ("0.00000000000001", False),  # 14 decimals
        ("1e5", True),
        ("nan", True),
        ("-inf", True),
    ],
)
def test_kernel_edge_numbers(value, odd):
    text = f"GOTO/{value},1,2\n" * 4
    got = list(kernel(text))
    assert len(got) == 4
    values = got[0][1]
    if odd:
        assert np.isnan(values).all()
    else:
        assert bits(values) == bits([float(value), 1.0, 2.0])
    # and the whole reading is the numpy path's
    assert_same_reading("MULTAX/ON\n" + text.replace(",1,2", ",1,2,0,0,1") + "FINI\n", least=2)


@pytest.mark.parametrize(
    "line",
    [
        "GOTO/1,2",
        "GOTO/1,2,3,4",
        "GOTO/1,,3",
        "GOTO/1,2,3 $",
        "GOTO/1,2,$",
        "GOTO/1,2,3 x",
        "GOTO/1 2,3,4",
        "GOTO/1,2,3,4,5,6,7",
        "GOTO/1,2,3\x0b",
        "goto/1,2,3",
        " GOTO/1,2,3",
        "GOTO /1,2,3",
        "GOTO/1,2,3\u00a0",
        "GOTO/1,2,3\u2009",
        "GOTO/1_0,2,3",
        "GOTO/-,2,3",
        "GOTO/.,2,3",
    ],
)
def test_lines_the_kernel_leaves_to_the_scanner(line):
    """Lines that are no plain GOTO line (odd ones left to np.loadtxt aside) are no line of a
    run, and the file reads as by the numpy path (the same error)."""
    text = "GOTO/0,0,0\n" * 3 + line + "\n" + "GOTO/0,0,1\n" * 3
    inside = [got for got, _ in kernel(text)]
    assert line not in inside or not ("$" in line or "_" in line or line.startswith(" "))
    assert_same_reading(text)
    assert_same_reading(text, least=1)


def test_comments_and_runs_of_mixed_widths():
    text = (
        "GOTO/1,2,3 $$ a comment, with commas\n" * 3
        + "GOTO/1,2,3,0,0,1$$x\n" * 4
        + "GOTO/1,2,3\n" * 2  # too few
        + "FEDRAT/100\n"
        + "GOTO/4,5,6\n" * 5
    )
    runs = goto_runs(np.frombuffer(text.encode(), dtype=np.uint8), 3, 1 << 30, 8, 8, 8)[0]
    assert runs[:, 2].tolist() == [3, 4, 7]  # GOTO lines (the feed line joins the last two)
    assert runs[:, 3].tolist() == [3, 6, 3]  # values per line
    assert runs[:, 4].tolist() == [3, 4, 0]  # comments
    assert runs[:, 7].tolist() == [0, 0, 1]  # feed lines
    assert_same_reading("MULTAX/ON\n" + text)


def test_kernel_cuts_long_runs():
    text = "".join(f"GOTO/{k}.5,{k},0\n" for k in range(1000))
    data = np.frombuffer(text.encode(), dtype=np.uint8)
    runs = goto_runs(data, 4, 200, 200, 0, 0)[0]
    # cut after the line that makes a piece 200 characters long
    assert (runs[:-1, 1] - runs[:-1, 0] >= 200).all()
    assert (runs[:-1, 1] - runs[:-1, 0] < 200 + 18).all()
    assert runs[:, 2].sum() == 1000
    assert runs[0, 0] == 0 and runs[-1, 1] == len(text)
    assert (runs[1:, 0] == runs[:-1, 1]).all()
    assert_same_reading(text, least=4, piece=200)


def test_kernel_says_when_it_needs_more_room(monkeypatch):
    """Runs and odd lines beyond the room given: the kernel says how many, and the reader
    calls it again with that room."""
    text = "".join(f"GOTO/{k},0,0\nGOTO/{k}e1,1,1\nRAPID\n" for k in range(300))
    data = np.frombuffer(text.encode(), dtype=np.uint8)
    runs, _, odd, _, _, runs_needed, odd_needed, _ = goto_runs(data, 1, 1 << 30, 10, 20, 0)
    assert (len(runs), len(odd), runs_needed, odd_needed) == (10, 20, 300, 300)
    full = goto_runs(data, 1, 1 << 30, 300, 300, 0)
    assert (full[0][:10] == runs).all() and (full[2][:20] == odd).all()
    monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 1)
    got = apt_module._compiled_runs(text, 1 << 30)
    assert got is not None and len(got) == 300
    assert [[start, end] for start, end, _, _, _ in got] == full[0][:, :2].tolist()
    assert bits(np.concatenate([v for _, _, v, _, _ in got])) == bits(
        [[k, 0, 0, 10 * k, 1, 1] for k in range(300)]
    )
    assert_same_reading(text, least=1)


# -- whole readings: the same toolpath or the same error --------------------------------------

_other_lines = st.sampled_from(
    [
        "RAPID",
        "FEDRAT/MMPM,500",
        "FEDRAT/IPM,20",
        "$$ comment",
        "",
        "   ",
        "GOTO/1,2,$",
        "3",
        " GOTO/1,2,3",
        "GOTO/1,2,3,4",
        "GOTO/x,1,2",
        "CIRCLE/0,0,0,0,0,1,5",
        "PPRINT GOTO/1,2,3",
        "MULTAX/ON",
        "UNITS/INCHES",
        "FINI",
        "GOTO/1e999,0,0",
        "GOTO/nan,0,0",
        "GOTO/1,2,3,0,0,0",
        "GOTO/1,2,3,0,0,2",
    ]
)


@st.composite
def goto_lines(draw: st.DrawFn) -> str:
    width = draw(st.sampled_from([3, 6]))
    values = [draw(st.one_of(fixed(), fixed(), numbers())) for _ in range(3)]
    if width == 6:  # mostly unit axes, sometimes not
        axis = draw(st.sampled_from(["0,0,1", "0.6,0,0.8", "-0.707107,0,0.707107", "0,0,1.5"]))
        values += axis.split(",")
    line = draw(st.sampled_from(["GOTO/", "GOTO/", "GOTO  /", "GOTO\t/ "])) + ",".join(values)
    if draw(st.integers(0, 7)) == 0:
        line += draw(st.sampled_from([" $$ x", "$$", " $$ 1,2,3"]))
    return line


#: Feed lines the bulk reader takes into a run (the numpy path not the one with a comment).
GOOD_FEEDS = [
    "FEDRAT/MMPM,500",
    "FEDRAT/ 800.0000,MMPM",
    "FEDRAT/IPM,20",
    "FEDRAT/250",
    "FEDRAT/ MMPM , 1250.5 ",
    "FEDRAT/MMPR,0.1",
    "FEDRAT/IPR,0.004",
    "FEDRAT/mmpm,300.5",
    "FEDRAT/MMPM,500 $$ a comment",
]
#: Feed lines that FEDRAT refuses, warns about or carries as unknown, or that the bulk reader
#: leaves to the scanner.
BAD_FEEDS = [
    "FEDRAT/MMPM,0",
    "FEDRAT/MMPM,-5",
    "FEDRAT/MMPM,1e3",
    "FEDRAT/MMPM,99999999",
    "FEDRAT/MMPR,9999",
    "FEDRAT/XYZ,5",
    "FEDRAT/NAN",
    "FEDRAT/MMPM,IPM,5",
    "FEDRAT/5,IPM",
    "FEDRAT/MMPM,$",
    "FEDRAT/1.0000000000000000001",
]
_feed_lines = st.sampled_from(GOOD_FEEDS + BAD_FEEDS)
_good_feed_lines = st.sampled_from(GOOD_FEEDS)


@st.composite
def feed_runs(draw: st.DrawFn) -> str:
    """GOTO lines with feed lines between them, as feed-optimised CL data writes them: mostly
    lines the bulk reader takes, sometimes any."""
    clean = draw(st.booleans())
    feeds = _good_feed_lines if clean else st.one_of(_good_feed_lines, _feed_lines)
    lines = [draw(st.sampled_from(["SPINDL/1000,CLW", "SPINDL/OFF", "RAPID", "$$ x"]))]
    for _ in range(draw(st.integers(1, 12))):
        for _ in range(draw(st.sampled_from([0, 1, 1, 1, 2]))):
            lines.append(draw(feeds))
        if clean:
            values = [draw(fixed()) for _ in range(3)]
            head = draw(st.sampled_from(["GOTO/", "GOTO  /  "]))
            axis = draw(st.sampled_from(["0.6,0,0.8", "0.6,0,0.8", "0.6,0,0.8 $$ c", "0,0,1.5"]))
            lines.append(head + ",".join([*values, axis]))
        else:
            lines.append(draw(goto_lines()))
    return "\n".join(lines)


@st.composite
def apt_texts(draw: st.DrawFn) -> str:
    blocks = draw(
        st.lists(
            st.one_of(
                st.lists(goto_lines(), min_size=1, max_size=12).map("\n".join),
                feed_runs(),
                _feed_lines,
                st.sampled_from(["SPINDL/1000,CLW", "SPINDL/OFF", "UNITS/MM"]),
                _other_lines,
            ),
            min_size=1,
            max_size=12,
        )
    )
    newline = draw(st.sampled_from(["\n", "\r\n"]))
    return newline.join(blocks) + draw(st.sampled_from(["", newline]))


@PROPERTY
@given(apt_texts(), st.sampled_from([1, 3, 32]), st.sampled_from([None, 60]))
def test_same_reading_as_the_numpy_path(text, least, piece):
    assert_same_reading(text, least, piece)


@PROPERTY
@given(
    apt_texts(),
    st.sampled_from([1, 3]),
    st.sampled_from([None, "mm", "inch"]),
    st.sampled_from([None, 60]),
)
def test_runs_read_as_record_by_record(text, least, units, piece):
    """Runs with feed lines (or without) read in bulk, by both paths, whole or cut into pieces
    of ``piece`` characters, give what reading every record alone gives (no run at all), with
    the file's units or the caller's."""

    def read() -> Toolpath:
        return read_cl_text(text, source="k.apt", format="apt", units=units)

    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 1 << 40)
        alone = outcome(read)
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", least)
        if piece is not None:
            monkeypatch.setattr(apt_module, "_BULK_PIECE", piece)
        numpy_way, compiled = both_ways(read)
    assert numpy_way == alone
    assert compiled == alone


def test_feed_lines_join_runs():
    """Feed-optimised data (a FEDRAT before every GOTO) is read as one run by both paths,
    with each move's feed and line."""
    lines = ["UNITS/MM", "MULTAX/ON", "SPINDL/1000,CLW", "FEDRAT/MMPM,900"]
    for k in range(200):
        if k <= 121:
            lines.append(f"FEDRAT/MMPM,{1000 + k}.5" if k < 121 else "FEDRAT/MMPR,0.25")
        lines.append(f"GOTO/{k}.0,1.0,2.0,0.0,0.0,1.0")
    text = "\n".join([*lines, "FINI", ""])
    for size in (NEVER, 0):
        with pytest.MonkeyPatch.context() as monkeypatch:
            compiled_from(monkeypatch, size)
            scan = apt_module.scan_text(text, "k.apt")
            runs = [r for r in scan.records if isinstance(r, apt_module.GotoRun)]
            # (the first feed line comes before the run's first GOTO: the scanner's)
            assert len(runs) == 1 and len(runs[0]) == 200 and len(runs[0].feeds) == 121
            path = read_cl_text(text, source="k.apt", format="apt")
    expected = [1000.5 + k for k in range(121)] + [0.25 * 1000] * 79  # per rev at 1000 rpm
    assert path.feed.tolist() == expected
    assert path.line.tolist() == [6 + 2 * min(k, 121) + max(k - 121, 0) for k in range(200)]


@pytest.mark.parametrize(
    "last",
    ["GOTO/0,0,0,0,0,1.5", "GOTO/0,0,0,0,0,1.5 $$ x", "GOTO/1e999,0,0,0,0,1", "GOTO/5,0,0,0,0,1"],
)
def test_a_feed_run_read_record_by_record_starts_from_the_feed_before_it(last):
    """A run with feed lines whose points need a message (a tool axis of another length, a
    number beyond the bounds) is read record by record: from the modal state before the run,
    not the one its feed lines would have left (the first GOTO keeps its unknown feed)."""
    text = f"SPINDL/1000,CLW\nGOTO/0,0,0,0.6,0,0.8\nFEDRAT/MMPM,500\nGOTO/0,0,0,0,0,1\n{last}\n"

    def read() -> Toolpath:
        return read_cl_text(text, source="k.apt", format="apt")

    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 1 << 40)
        alone = outcome(read)
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 1)
        assert both_ways(read) == (alone, alone)
    if not isinstance(alone, tuple):  # (not an error)
        assert math.isnan(read().feed[0])


@pytest.mark.parametrize("units", [None, "mm", "inch"])
def test_feed_runs_with_the_callers_units(units):
    """Feed keywords of other units than the caller's: the first one is warned about (read
    record by record), the later runs read in bulk with the caller's unit, as record by
    record."""
    lines = ["MULTAX/ON"]
    for run in range(3):
        lines.append("RAPID")
        for k in range(40):
            word = ("MMPM", "IPM", "")[(run + k) % 3]
            lines += [f"FEDRAT/{word}{',' if word else ''}{10 + k}", f"GOTO/{k},{run},0,0,0,1"]
    text = "\n".join([*lines, "FINI", ""])

    def read() -> Toolpath:
        return read_cl_text(text, source="k.apt", format="apt", units=units)

    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 1 << 40)
        alone = outcome(read)
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 8)
        assert both_ways(read) == (alone, alone)
    scan = apt_module.scan_text(text, "k.apt")
    assert sum(isinstance(r, apt_module.GotoRun) for r in scan.records) == 3


@PROPERTY
@given(apt_texts(), st.sampled_from([1, 3]), st.sampled_from([40, 1 << 18]))
def test_same_reading_in_pieces(tmp_path_factory, text, least, part):
    path = tmp_path_factory.mktemp("k") / "k.apt"
    path.write_bytes(text.encode())
    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", least)
        monkeypatch.setattr(apt_module, "_STREAM_PART", part)
        whole = both_ways(lambda: read_cl(path, format="apt"))
        pieces = both_ways(
            lambda: list(read_cl_chunks(path, max_points=3, format="apt", _text_piece=16))
        )
    assert whole[1] == whole[0]
    assert pieces[1] == pieces[0]


def hemisphere(points: int, decimals: int = 4) -> str:
    """A generated job like bench/make_large_cl.py's: layers of GOTO runs with the tool axis
    normal to a sphere, feeds and rapids between them."""
    out = ["PARTNO TEST", "UNITS/MM", "MULTAX/ON", "LOADTL/1", "SPINDL/12000,CLW"]
    per_layer = points // 4
    for layer in range(4):
        t = np.linspace(0.1, 1.4, per_layer)
        phi = layer * math.pi / 4 + 20 * t
        axis = np.stack([np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.cos(t)], axis=1)
        tip = 40 * axis
        out += [f"PPRINT LAYER {layer}", "RAPID", "FEDRAT/MMPM,2000.0"]
        out += [
            f"GOTO/{x:.{decimals}f},{y:.{decimals}f},{z:.{decimals}f},{i:.6f},{j:.6f},{k:.6f}"
            for (x, y, z), (i, j, k) in zip(tip, axis, strict=True)
        ]
    return "\n".join([*out, "FINI", ""])


@pytest.mark.parametrize("decimals", [0, 3, 4, 7])
def test_generated_job(tmp_path, decimals):
    text = hemisphere(20_000, decimals)
    assert_same_reading(text, least=32)
    path = tmp_path / "h.apt"
    path.write_bytes(text.replace("\n", "\r\n").encode())
    whole = both_ways(lambda: read_cl(path))
    assert whole[1] == whole[0]
    pieces = both_ways(lambda: list(read_cl_chunks(path, max_points=3000)))
    assert pieces[1] == pieces[0]


@pytest.mark.parametrize(
    "name", ["nx_project2_15ops_inch.cls", "nx_variable_axis_ballmill_inch.cls"]
)
@pytest.mark.parametrize("least", [3, 32])
def test_real_files(name, least):
    path = SHARED_CL / name
    if not path.is_file():
        pytest.skip(f"{path} absent (the shared test data is not in a fresh clone)")
    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", least)
        whole = both_ways(lambda: read_cl(path))
        pieces = both_ways(lambda: list(read_cl_chunks(path, max_points=1000)))
    assert isinstance(whole[0], list)
    assert whole[1] == whole[0]
    assert pieces[1] == pieces[0]


def test_the_kernel_reads_the_runs_of_a_real_file():
    """The real NX file's GOTO runs are found by the loop, their numbers read by it."""
    path = SHARED_CL / "nx_project2_15ops_inch.cls"
    if not path.is_file():
        pytest.skip(f"{path} absent (the shared test data is not in a fresh clone)")
    text = apt_module.normalise_breaks(path.read_text())
    got = list(kernel(text, least=3))
    assert len(got) > 5000
    for line, values in got:
        code = line.partition("$$")[0]
        assert bits(values) == bits([float(v) for v in code[5:].split(",")]), line


@PROPERTY
@given(
    st.lists(
        st.sampled_from(
            [
                *("GOTO/1,2,3", "GOTO/P", "GOTO/$", "GOTO/p", "GOTO", " GOTO/1", "", "X"),
                *("GOTO  /1,2,3", "GOTO /P", "GOTO 1"),
                *("FEDRAT/MMPM,5", "FEDRAT/5 $$ x", "FEDRAT/5,$", "FEDRAT", " FEDRAT/5"),
            ]
        ),
        max_size=6,
    ),
    st.booleans(),
    st.booleans(),
)
def test_plain_goto_lines_is_the_str_test(lines, end, feeds):
    text = "\n".join(lines) + ("\n" if end else "")
    count, plain = plain_goto_lines(np.frombuffer(text.encode(), dtype=np.uint8), feeds)
    assert count == line_count(text)
    assert plain == apt_module._only_plain_gotos(text, count, feeds)


# -- errors, fallbacks -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        ("GOTO/1,2,x3", r"k\.apt:6: expected a number for the 3rd value of GOTO, got 'x3'"),
        ("GOTO/1,2,3,4", r"k\.apt:6: expected 3 or 6 values in GOTO, got 4"),
        ("GOTO/1,,3", r"k\.apt:6: expected a number for the 2nd value of GOTO, got ''"),
        ("GOTO/1e999,2,3", r"k\.apt:6: expected a finite number for the 1st value of GOTO"),
        ("GOTO/nan,2,3", r"k\.apt:6: expected a finite number for the 1st value of GOTO"),
        ("GOTO/1_000,2,3", r"k\.apt:6: expected a number for the 1st value of GOTO, got '1_000'"),
        ("GOTO/1,2,$", r"k\.apt:6: expected the continuation of this record"),
    ],
)
def test_bad_lines_give_the_same_error(bad, message):
    text = "".join(f"GOTO/{k},0,0\n" for k in range(5)) + bad + "\n"
    text += "".join(f"GOTO/{k},0,1\n" for k in range(5))
    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 2)
        numpy_way, compiled = both_ways(lambda: read_cl_text(text, source="k.apt"))
    assert compiled == numpy_way
    assert isinstance(compiled, tuple), compiled
    assert re.search(message, compiled[1]), compiled[1]


def test_odd_line_numpy_refuses_falls_back_to_the_numpy_path(monkeypatch):
    """An odd line whose numbers np.loadtxt does not read: the text goes the numpy way."""
    text = "GOTO/1,2,3\n" * 3 + "GOTO/1,2,3e\n" + "GOTO/1,2,3\n" * 3
    monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 2)
    assert apt_module._compiled_runs(text, 1 << 20) is None
    assert_same_reading(text, least=2)


def test_odd_lines_are_read_by_loadtxt(monkeypatch):
    text = "".join(f"GOTO/{k}e-1,1.00000000000000000001,{k}\n" for k in range(6))
    monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 2)
    runs = apt_module._compiled_runs(text, 1 << 20)
    assert runs is not None and len(runs) == 1
    values = runs[0][2]
    assert bits(values) == bits([[float(f"{k}e-1"), 1.0, k] for k in range(6)])


def test_without_numba_the_numpy_path_runs(monkeypatch, unloaded):
    import builtins

    real_import = builtins.__import__

    def no_kernels(name: str, *args: object, **kwargs: object) -> object:
        if name == "urdfpost.readers" and "_goto_kernel" in (args[2] or ()):  # type: ignore[operator]
            raise ImportError("no numba here")
        return real_import(name, *args, **kwargs)  # type: ignore[arg-type]

    text = hemisphere(400)
    unloaded(apt_module.KERNELS)
    compiled_from(monkeypatch, 0)
    with monkeypatch.context() as m:
        m.setattr(builtins, "__import__", no_kernels)
        assert apt_module._compiled_runs(text, 1 << 20) is None
    got = outcome(lambda: read_cl_text(text))
    compiled_from(monkeypatch, NEVER)
    assert got == outcome(lambda: read_cl_text(text))


def test_a_failing_kernel_falls_back_with_a_warning(monkeypatch, caplog, stand_in):
    def broken(*args: object) -> None:
        raise RuntimeError("no LLVM here")

    text = hemisphere(400)
    expected = outcome(lambda: read_cl_text(text))
    stand_in(apt_module.KERNELS, SimpleNamespace(goto_runs=broken, plain_goto_lines=broken))
    compiled_from(monkeypatch, 0)
    with caplog.at_level(logging.WARNING, logger="urdfpost.readers.apt"):
        assert outcome(lambda: read_cl_text(text)) == expected
        assert outcome(lambda: read_cl_text(text)) == expected
    warned = [r for r in caplog.records if "compiled GOTO scan unavailable" in r.message]
    assert len(warned) == 1  # once: the numpy path runs from then on
    assert "no LLVM here" in warned[0].message


def test_small_texts_do_not_load_the_kernel(monkeypatch):
    def refused() -> None:
        raise AssertionError("the compiled loop was looked for")

    monkeypatch.setattr(apt_module.KERNELS, "load", refused)
    read_cl_text(hemisphere(400))


def test_the_threshold_is_lower_once_numba_is_imported(monkeypatch):
    assert "numba" in sys.modules  # (imported above)
    assert apt_module.COMPILED_WARM_FROM < apt_module.COMPILED_FROM
    assert apt_module.KERNELS.wanted(apt_module.COMPILED_WARM_FROM)
    assert not apt_module.KERNELS.wanted(apt_module.COMPILED_WARM_FROM - 1)
    monkeypatch.delitem(sys.modules, "numba")
    assert not apt_module.KERNELS.wanted(apt_module.COMPILED_WARM_FROM)
    assert apt_module.KERNELS.wanted(apt_module.COMPILED_FROM)


def test_the_size_threshold_applies_to_streamed_files(tmp_path, monkeypatch):
    path = tmp_path / "h.apt"
    path.write_text(hemisphere(400))
    calls: list[int] = []
    real = apt_module._compiled_runs

    def counted(text: str, size: int) -> object:
        calls.append(len(text))
        return real(text, size)

    monkeypatch.setattr(apt_module, "_compiled_runs", counted)
    list(read_cl_chunks(path, max_points=100))
    assert not calls
    compiled_from(monkeypatch, path.stat().st_size)
    list(read_cl_chunks(path, max_points=100))
    assert calls


def test_feed_keywords_by_code():
    """Both paths give a feed line's keyword the same code, in any case and on either side of
    the number; an unknown keyword ends the run there (the scanner reads it)."""
    words = ["MMPM", "ipm", "Mmpr", "IPR", ""]
    lines = ["SPINDL/1000,CLW", "GOTO/0,0,0"]
    for k in range(40):
        word = words[k % 5]
        if not word:
            lines.append("FEDRAT/12.5")
        elif k % 2:
            lines.append(f"FEDRAT/ {word} , 0.5")
        else:
            lines.append(f"FEDRAT/0.5,{word}")
        lines.append(f"GOTO/{k},0,0")
    lines += ["FEDRAT/INVERS,5", "GOTO/1,1,1", "GOTO/2,2,2"]
    text = "\n".join([*lines, "FINI", ""])
    for size in (NEVER, 0):
        with pytest.MonkeyPatch.context() as monkeypatch:
            compiled_from(monkeypatch, size)
            monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", 2)
            scan = apt_module.scan_text(text, "k.apt")
        runs = [r for r in scan.records if isinstance(r, apt_module.GotoRun)]
        assert [len(r) for r in runs] == [41, 2]
        got = [apt_module.FEED_KEYWORDS[c] for c in runs[0].feeds.keywords.tolist()]
        assert got == [words[k % 5].upper() for k in range(40)]
        assert runs[1].feeds is None
        assert any(
            getattr(r, "word", "") == "FEDRAT" and r.args[0] == "INVERS" for r in scan.records
        )
