"""Fuzzing of the CL readers (issue 22): random bytes, random text and random mutations of
real records.

Two properties, for every reader entry point (``read_cl``, ``read_cl_text``,
``read_cl_chunks``; the format detected, and each format given):

1. Whatever the input, a reader returns a toolpath or raises an :class:`UrdfpostError`
   (a :class:`CLDataError`): never another exception. The whole and the streamed reading
   agree (the same toolpath in pieces, or the same error).
2. No motion record is dropped silently: every GOTO record of the input (counted here with
   a small scanner of its own, :func:`goto_records`) is a point of the toolpath, or the
   reading raises.

The examples are few by default (the suite stays fast); ``CI=true`` runs five times as many
and ``URDFPOST_HYPOTHESIS_SCALE=N`` multiplies them again (a long run).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import SHARED_CL
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import urdfpost.readers.apt as apt_module
from urdfpost.errors import CLDataError, UrdfpostError
from urdfpost.readers import FORMATS, read_cl, read_cl_chunks, read_cl_text
from urdfpost.readers._encoding import HEAD_BYTES, encoding_of
from urdfpost.toolpath import Toolpath

CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")
SCALE = int(os.environ.get("URDFPOST_HYPOTHESIS_SCALE", "1")) * (5 if CI else 1)
FUZZ = settings(
    max_examples=40 * SCALE,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

DATA = Path(__file__).parent / "data" / "cl"
FIELDS = ("tip", "axis", "feed", "motion", "line")


def real_lines() -> list[list[str]]:
    """The lines of every real CL file: tests/data and ../shared (when present)."""
    paths = sorted(DATA.iterdir())
    if SHARED_CL.is_dir():
        paths += sorted(SHARED_CL.glob("*.cls"))
    return [re.split(r"\r\n|\r|\n", p.read_text()) for p in paths if p.is_file()]


REAL_LINES = real_lines()


# -- an independent count of the GOTO records ---------------------------------------------------

_FREE_TEXT = re.compile(r"(PPRINT|PARTNO|INSERT)(?![A-Za-z0-9_])", re.I)
_LISTING = re.compile(
    r"(?:information listing created by\b|(?:date|current work part|node name)\s*[:\t]"
    r"|tool path listing has \d+ lines\b)",
    re.I,
)
_RULE = re.compile(r"[-=]{3,}\s*$")
_FINI = re.compile(r"[Ff][Ii][Nn][Ii][ \t]*(?:/.*)?", re.S)


def records_of(text: str) -> list[tuple[int, str]]:
    """(first line, text) of each record up to FINI, as an APT file defines them: a line
    ending with ``$`` goes on on the next non-blank line, ``$$`` starts a comment (a whole
    line of one is no record), PPRINT/PARTNO/INSERT are one line of free text, NX listing
    lines and rules of dashes are no records."""
    records: list[tuple[int, str]] = []
    pending: str | None = None
    start = 0
    for number, raw in enumerate(re.split(r"\r\n|\r|\n", text), start=1):
        line = raw.strip()
        if not line or line.startswith("$$"):
            continue
        if pending is None and (_LISTING.match(line) or _RULE.match(line)):
            continue
        if pending is None and _FREE_TEXT.match(line):
            records.append((number, line))
            continue
        code = line.split("$$", 1)[0].rstrip()
        continued = code.endswith("$")
        code = code[:-1] if continued else code
        if pending is None:
            pending, start = code, number
        else:
            pending += code
        if continued:
            continue
        records.append((start, pending.strip()))
        pending = None
        if _FINI.fullmatch(records[-1][1]):
            break
    return records


def goto_records(text: str) -> tuple[list[int], list[int]]:
    """Lines of the GOTO records and of the CIRCLE records of an APT text (up to FINI)."""
    records = records_of(text)
    gotos = [n for n, code in records if re.match(r"[Gg][Oo][Tt][Oo][ \t]*/", code)]
    circles = [n for n, code in records if re.match(r"CIRCLE[ \t]*/", code, re.I)]
    return gotos, circles


def assert_no_goto_dropped(text: str, toolpath: Toolpath) -> None:
    """Every GOTO record of ``text`` is a point of ``toolpath``: one point on its own line,
    or the last point of the arc of the CIRCLE before it (the arc's points carry the CIRCLE's
    line)."""
    gotos, circles = goto_records(text)
    lines, counts = np.unique(toolpath.line, return_counts=True)
    on_goto = {int(n): int(c) for n, c in zip(lines, counts, strict=True) if int(n) in gotos}
    assert all(c == 1 for c in on_goto.values()), on_goto  # one point per GOTO
    arcs = {int(n) for n in lines} & set(circles)
    assert len(on_goto) + len(arcs) == len(gotos), (gotos, sorted(on_goto), sorted(arcs))


# -- reading every way ---------------------------------------------------------------------------


def outcome(read: Callable[[], object]) -> object:
    """What ``read()`` returns, or the error it raises (an urdfpost error, comparable)."""
    try:
        return read()
    except CLDataError as exc:
        return ("CLDataError", exc.path, exc.line, str(exc))
    except UrdfpostError as exc:  # pragma: no cover - readers raise CLDataError
        return (type(exc).__name__, str(exc))


def joined(pieces: list[Toolpath]) -> tuple:
    """The pieces as comparable values: their arrays joined, events re-indexed, warnings."""
    arrays = tuple(np.concatenate([getattr(p, f) for p in pieces]).tobytes() for f in FIELDS)
    events, offset = [], 0
    for piece in pieces:
        events += [(e.index + offset, e.kind, e.line, repr(e.data)) for e in piece.events]
        offset += len(piece)
    warnings = tuple(w for p in pieces for w in p.warnings)
    return arrays, events, warnings, pieces[-1].units, pieces[-1].multiaxis


def read_every_way(path: Path, data: bytes, max_points: int, text_piece: int) -> list[object]:
    """The toolpath of ``data`` (written to ``path``) read whole and in pieces, the format
    detected and each format given; each an outcome (the toolpath as :func:`joined`)."""
    path.write_bytes(data)
    out = []
    for format in (None, *FORMATS):
        whole = outcome(lambda format=format: read_cl(path, format=format))
        pieces = outcome(
            lambda format=format: list(
                read_cl_chunks(path, max_points=max_points, format=format, _text_piece=text_piece)
            )
        )
        if isinstance(whole, Toolpath):
            assert isinstance(pieces, list), pieces
            assert joined(pieces) == joined([whole])
            out.append(whole)
        else:
            assert pieces == whole
            out.append(whole)
    return out


def text_of(data: bytes) -> str | None:
    """The text the readers read from a file of ``data`` (its byte-order mark decoded, bad
    bytes replaced), or None when it holds a NUL (an error at its line, whatever the rest)."""
    codec, mark = encoding_of(data[:HEAD_BYTES])
    text = data[mark:].decode(codec, "replace")
    return None if "\x00" in text else text


def check_bytes(path: Path, data: bytes, how: tuple[int, int, int, int]) -> None:
    """Properties 1 and 2 for one input (2 for what the APT reader reads), and the text
    readers give what the file readers give.

    ``how``: the most points in a piece, the bytes read at a time, the fewest GOTO lines read
    in bulk and the characters scanned at a time by the streamed APT reader (small values
    take the bulk reader and the cuts between pieces into short inputs).
    """
    max_points, text_piece, bulk_min, stream_part = how
    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.setattr(apt_module, "BULK_MIN_RECORDS", bulk_min)
        monkeypatch.setattr(apt_module, "_STREAM_PART", stream_part)
        check_read(path, data, max_points, text_piece)


def check_read(path: Path, data: bytes, max_points: int, text_piece: int) -> None:
    """:func:`check_bytes` with the reader's settings made."""
    got = read_every_way(path, data, max_points, text_piece)
    text = text_of(data)
    if text is None:
        return
    apt = got[1 + list(FORMATS).index("apt")]
    if isinstance(apt, Toolpath):
        assert_no_goto_dropped(text, apt)
    for k, format in enumerate((None, *FORMATS)):
        from_text = outcome(
            lambda format=format: read_cl_text(text, source=str(path), format=format)
        )
        if isinstance(got[k], Toolpath):
            assert isinstance(from_text, Toolpath), from_text
            assert joined([from_text]) == joined([got[k]])
        else:
            assert from_text == got[k]


#: How to read: (max_points, text_piece, BULK_MIN_RECORDS, _STREAM_PART), see check_bytes.
_how = st.tuples(
    st.integers(1, 5),
    st.sampled_from([1, 3, 16, 1 << 20]),
    st.sampled_from([apt_module.BULK_MIN_RECORDS, 3]),
    st.sampled_from([apt_module._STREAM_PART, 40]),
)


# -- 1. random bytes and text --------------------------------------------------------------------

#: Pieces of CL text, joined at random: records, numbers, separators, line breaks, odd bytes.
_TOKENS = [
    b"GOTO/",
    b"goto / ",
    b"CIRCLE/",
    b"FROM/",
    b"GODLTA/",
    b"FEDRAT/",
    b"LOADTL/",
    b"LOAD/TOOL,",
    b"ADJUST,",
    b"LENGTH,",
    b"SPINDL/",
    b"RAPID",
    b"MULTAX",
    b"UNITS/INCHES",
    b"MSYS/",
    b"TOOL PATH/",
    b"TIMES,",
    b"PPRINT ",
    b"INSERT ",
    b"FINI",
    b"IPM,",
    b"MMPR,",
    b"1",
    b"0",
    b"-",
    b".5",
    b"10",
    b"1e3",
    b"1e308",
    b"nan",
    b"inf",
    b"9" * 40,
    b",",
    b",",
    b",",
    b" ",
    b"\t",
    b"$",
    b"$$",
    b"\n",
    b"\n",
    b"\r\n",
    b"\r",
    b"--------",
    b"Tool Path Listing has 3 lines.",
    b"1 2 3\n",
    b"0, 0.6, 0.8",
    b"#",
    b";",
    b"CIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n",
    b"GOTO/10,0,0\n",
    b"PAINT/COLOR,3\n",
    b"\xef\xbb\xbf",
    b"\xff\xfe",
    b"\xff",
    b"\xc3\xa9",
    b"\x0c",
    b"\x00",
]
_cl_like = st.lists(st.sampled_from(_TOKENS), max_size=200).map(b"".join)


@FUZZ
@given(data=st.binary(max_size=3000), how=_how)
def test_random_bytes(tmp_path, data, how):
    check_bytes(tmp_path / "random.apt", data, how)


@FUZZ
@given(text=st.text(max_size=2000), how=_how)
def test_random_text(tmp_path, text, how):
    check_bytes(tmp_path / "random.cl", text.encode(), how)


@FUZZ
@given(data=_cl_like, how=_how)
def test_random_cl_like_bytes(tmp_path, data, how):
    check_bytes(tmp_path / "cl_like.apt", data, how)


# -- 2. random mutations of real records ---------------------------------------------------------

_CHARS = "0123456789.,-+/$ \tEeGOTXYZ_é\x0c"
#: Records inserted among real ones.
_RECORDS = [
    "RAPID",
    "FINI",
    "UNITS/INCHES",
    "UNITS/MM",
    "MULTAX/ON",
    "FEDRAT/IPR,0.1",
    "SPINDL/OFF",
    "TOOL PATH/X,TOOL,Y",
    "MSYS/1,2,3,0,1,0,-1,0,0",
    "CIRCLE/0,0,0,0,0,1,1",
    "GODLTA/1",
    "LOADTL/3,ADJUST,7",
    "PPRINT note $",
    "$$ note",
    "--------",
    "FROB/1",
]


@st.composite
def mutated_records(draw: st.DrawFn) -> str:
    """A run of lines of a real CL file with a few random mutations: a character changed,
    inserted or deleted, a line deleted or duplicated, a ``$`` inserted, a record split."""
    assume(REAL_LINES)
    source = draw(st.sampled_from(REAL_LINES))
    start = draw(st.integers(0, max(0, len(source) - 1)))
    lines = source[start : start + draw(st.integers(1, 60))]
    if draw(st.booleans()):  # the file's head: its units and dialect
        lines = source[:12] + lines
    for _ in range(draw(st.integers(1, 4))):
        k = draw(st.integers(0, len(lines) - 1))
        line = lines[k]
        at = draw(st.integers(0, len(line)))
        kind = draw(
            st.sampled_from(
                ["change", "insert", "delete", "drop", "twice", "dollar", "split", "record"]
            )
        )
        if kind == "change" and line:
            at = min(at, len(line) - 1)
            lines[k] = line[:at] + draw(st.sampled_from(_CHARS)) + line[at + 1 :]
        elif kind == "insert":
            lines[k] = line[:at] + draw(st.sampled_from(_CHARS)) + line[at:]
        elif kind == "delete" and line:
            at = min(at, len(line) - 1)
            lines[k] = line[:at] + line[at + 1 :]
        elif kind == "drop" and len(lines) > 1:
            del lines[k]
        elif kind == "twice":
            lines.insert(k, line)
        elif kind == "dollar":
            lines[k] = line[:at] + "$" + line[at:]
        elif kind == "split":
            lines[k : k + 1] = [line[:at] + draw(st.sampled_from(["$", ""])), line[at:]]
        elif kind == "record":
            lines.insert(k, draw(st.sampled_from(_RECORDS)))
    newline = draw(st.sampled_from(["\n", "\r\n"]))
    return newline.join(lines) + draw(st.sampled_from(["", newline]))


@FUZZ
@given(text=mutated_records(), how=_how)
def test_mutated_real_records(tmp_path, text, how):
    check_bytes(tmp_path / "mutated.cls", text.encode(), how)


# -- the independent count itself ----------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "gotos", "circles"),
    [
        ("GOTO/1,2,3\nGOTO / 1,2,$\n3\n$$ GOTO/4,5,6\nPPRINT GOTO/7,8,9\n", [1, 2], []),
        ("GO$\nTO/1,2,3\nFEDRAT/$\nFINI\nGOTO/1,2,3\nFINI\nGOTO/4,5,6\n", [1, 5], []),
        ("GOTO/1,0,0\nCIRCLE/0,0,0,0,0,1,1\nGOTO/0,1,0\nFINI $\n/x\nGOTO/1,1,1\n", [1, 3], [2]),
    ],
)
def test_goto_records(text, gotos, circles):
    assert goto_records(text) == (gotos, circles)


def test_every_goto_of_the_real_files_is_a_point():
    """The independent count agrees with the reader on every real file (read whole)."""
    paths = sorted(DATA.iterdir()) + (sorted(SHARED_CL.glob("*.cls")) if SHARED_CL.is_dir() else [])
    counted = 0
    for path in paths:
        text = path.read_text()
        if FORMATS["apt"].detect and FORMATS["apt"].detect(text, True):
            assert_no_goto_dropped(text, read_cl(path))
            counted += len(goto_records(text)[0])
    assert counted >= 10
