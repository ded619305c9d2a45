"""The compiled reading of plain motion blocks (:mod:`urdfpost.dialects._line_kernel`).

:func:`urdfpost.dialects._bulk.motion_lines` with ``compiled=True`` must give the arrays of the
numpy path and of the whole-text reference of ``tests/test_dialect_speedpaths.py``, bit for bit,
for every control's grammar and any text; the reader must give the same programs and the same
errors whichever path reads; and without numba, or with numba failing, the numpy path reads.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import StandIn
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_dialect_speedpaths import (
    GRAMMARS,
    NASTY,
    _program,
    assert_same,
    outcome,
    reference_motion_lines,
    texts,
)
from test_dialects import EDITS, _long_program, _outcome

import urdfpost.dialects.reader as reader_module
from urdfpost.dialects import DIALECTS, _bulk
from urdfpost.program import Move, Program, ToolChange

pytest.importorskip("numba")

NAMES = sorted(DIALECTS)
GOLDEN = Path(__file__).parent / "golden"
#: The grammars the compiled loop reads (keywords of letters only): the controls' and odd ones.
COMPILED_GRAMMARS = sorted(
    name
    for name, grammar in GRAMMARS.items()
    if _bulk._letters_only(grammar.lead) and _bulk._letters_only(grammar.rapid_word)
)
#: A run of digits too long for the compiled loop (it leaves such a text to the numpy path).
LONG_NUMBER = re.compile(r"\d{16}")


def compiled(text: str, grammar: _bulk.MotionGrammar) -> _bulk.MotionLines | None:
    """The compiled loop's reading of a text, or None where it leaves the text to numpy."""
    return _bulk._compiled_lines(text.encode("ascii", "replace"), grammar)


def check(text: str, grammar: _bulk.MotionGrammar) -> _bulk.MotionLines | None:
    """``motion_lines`` compiled is the reference and the numpy path, bit for bit; returns
    the compiled loop's own reading (None when it left the text to the numpy path)."""
    want = outcome(lambda: reference_motion_lines(text, grammar))
    assert_same(outcome(lambda: _bulk.motion_lines(text, grammar, compiled=True)), want)
    numpy = _bulk.motion_lines(text, grammar)
    assert_same(numpy, want)
    own = compiled(text, grammar) if text else None
    if own is not None:
        assert_same(own, want)
    return own


@pytest.fixture(autouse=True)
def _kernel_works(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test starts with the compiled loop usable (a test may break it)."""
    monkeypatch.setattr(_bulk.KERNELS, "failed", None)


# -- texts ------------------------------------------------------------------------------------


@pytest.mark.parametrize("grammar", COMPILED_GRAMMARS)
@pytest.mark.parametrize("text", NASTY, ids=range(len(NASTY)))
def test_nasty_texts_read_alike(text: str, grammar: str) -> None:
    own = check(text, GRAMMARS[grammar])
    # the compiled loop declines only texts with a number of more than 15 digits (in a block
    # that is plain but for it)
    assert own is not None or not text or LONG_NUMBER.search(text)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(text=texts(), grammar=st.sampled_from(COMPILED_GRAMMARS))
def test_random_texts_read_alike(text: str, grammar: str) -> None:
    check(text, GRAMMARS[grammar])


@st.composite
def numbers(draw: st.DrawFn, point: bool = True) -> str:
    """The text of a number as a control or a hand may write it: signs, leading zeros, no
    digits before or after the point, up to 11 digits (17 now and then); now and then a
    malformed one."""
    sign = draw(st.sampled_from(["", "", "-", "+"]))
    long = draw(st.integers(0, 49)) == 0
    whole = draw(st.text("0123456789", max_size=9 if long else 6))
    fraction = draw(st.text("0123456789", max_size=8 if long else 5))
    mark = "." if point or draw(st.booleans()) else ""
    if draw(st.integers(0, 19)) == 0:
        mark = draw(st.sampled_from(["", "..", "-", "+", "e"]))
    if not (whole or fraction) and draw(st.integers(0, 3)):
        whole = "0"
    return sign + whole + mark + fraction


@st.composite
def motion_lines(draw: st.DrawFn) -> tuple[str, str]:
    """A grammar, and lines of motion blocks of it: block number, code or lead, axes in order,
    rapid word, feed; now and then a word out of place or missing, a blank or a character no
    plain block has."""
    name = draw(st.sampled_from(COMPILED_GRAMMARS))
    grammar = GRAMMARS[name]
    lines = []
    for _ in range(draw(st.integers(1, 30))):
        words = []
        if grammar.number_required or draw(st.booleans()):
            words.append(grammar.number_letter + str(draw(st.integers(0, 99999))))
        if grammar.lead:
            words.append(grammar.lead)
        elif grammar.codes and draw(st.booleans()):
            words.append(draw(st.sampled_from(["G0", "G1", "G01", "G00", "G1.0", "G2", "G1.5"])))
        axes = draw(st.lists(st.sampled_from("XYZABC"), min_size=1, max_size=6, unique=True))
        words += [a + draw(numbers(grammar.require_point)) for a in "XYZABC" if a in axes]
        if grammar.rapid_word and draw(st.booleans()):
            words.append(grammar.rapid_word)
        if draw(st.booleans()):
            words.append("F" + draw(numbers(False)))
        if draw(st.integers(0, 5)) == 0:  # damaged
            k = draw(st.integers(0, len(words) - 1))
            how = draw(st.integers(0, 3))
            if how == 0:
                words.insert(k, words.pop())
            elif how == 1:
                del words[k]
            else:
                at = draw(st.integers(0, len(words[k])))
                bad = draw(st.sampled_from([" ", "  ", "x", ";", "(", "\r", "é", "E", "."]))
                words[k] = words[k][:at] + bad + words[k][at:]
        lines.append(" ".join(words))
    return name, "\n".join(lines) + draw(st.sampled_from(["", "\n"]))


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=motion_lines())
def test_random_motion_lines_read_alike(case: tuple[str, str]) -> None:
    name, text = case
    check(text, GRAMMARS[name])


@settings(max_examples=300, deadline=None)
@given(
    values=st.lists(
        st.one_of(
            st.floats(-1e6, 1e6, allow_nan=False),
            st.integers(-(10**15) + 1, 10**15 - 1).map(lambda k: k / 10 ** (abs(k) % 16)),
            st.sampled_from([0.0, -0.0, 0.1 + 0.2, 1e-15, -9.999999999999999]),
        ),
        min_size=1,
        max_size=30,
    ),
    decimals=st.integers(0, 15),
)
def test_numbers_are_those_of_float(values: list[float], decimals: int) -> None:
    """Every number of up to 15 digits is read as ``float`` reads its text."""
    words = [f"X{v:.{decimals}f}" for v in values]
    words = [w for w in words if len(w.replace("-", "").replace(".", "")) <= 16]
    if not words:
        return
    text = "\n".join(f"G1 {w}" for w in words) + "\n"
    own = compiled(
        text, _bulk.MotionGrammar("N", False, None, {1.0: False, 0.0: True}, None, False)
    )
    assert own is not None and own.plain.all()
    want = np.array([float(w[1:]) for w in words])
    assert own.axes[:, 0].tobytes() == want.tobytes()


# -- programs ---------------------------------------------------------------------------------


def _golden_texts() -> list[tuple[str, Path]]:
    found = []
    for path in sorted(GOLDEN.glob("*/*")):
        for name in NAMES:
            if path.suffix in DIALECTS[name].extensions:
                found.append((name, path))
    return found


@pytest.mark.parametrize(("name", "path"), _golden_texts(), ids=lambda v: getattr(v, "name", v))
def test_golden_programs_read_alike(name: str, path: Path) -> None:
    text = path.read_text()
    grammar = GRAMMARS[name]
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    own = check(text, grammar)
    assert own is not None


def _random_program(seed: int, count: int, units: str) -> Program:
    """Moves of every size and sign, rapids, feed changes, signed zeros."""
    rng = np.random.default_rng(seed)
    blocks: list = [ToolChange(2)]
    for k in range(count):
        scale = 10.0 ** rng.integers(-4, 4)
        x, y, z = rng.uniform(-1, 1, 3) * scale
        b, c = rng.uniform(-120, 120), rng.uniform(-720, 720)
        if k % 101 == 0:
            x, c = -0.0, 0.0
        feed = None if k % 17 == 0 else float(rng.integers(1, 50_000)) / 10
        blocks.append(Move(k % 29 == 0, (x, y, z, b, c), feed))
    return Program("R", ("X", "Y", "Z", "B", "C"), frozenset("BC"), units, False, tuple(blocks))


@pytest.mark.parametrize("units", ["mm", "inch"])
@pytest.mark.parametrize("block_numbers", [None, True])
@pytest.mark.parametrize("name", NAMES)
def test_written_programs_read_alike(name: str, block_numbers: bool | None, units: str) -> None:
    for program in (_program(units), _random_program(7, 5_000, units)):
        text = DIALECTS[name].write(program, block_numbers=block_numbers)
        own = check(text, GRAMMARS[name])
        assert own is not None and own.plain.sum() > 500


def _read(
    monkeypatch: pytest.MonkeyPatch, name: str, text: str, compiled_from: int, **kwargs: object
) -> object:
    """``read`` of the text (its repr, or its error's type and message), compiled from
    ``compiled_from`` characters on."""
    monkeypatch.setattr(reader_module, "COMPILED_FROM", compiled_from)
    return _outcome(lambda: repr(DIALECTS[name].read(text, path="job", **kwargs)))


@pytest.mark.parametrize("name", NAMES)
def test_programs_read_alike(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Whole programs (the reader in pieces of 20k characters): the same blocks, feeds and
    modal state compiled as by numpy."""
    monkeypatch.setattr(reader_module, "_BULK_PIECE", 20_000)
    numbers = None if name == "heidenhain" else True
    for program in (_long_program(3_000), _random_program(3, 3_000, "inch")):
        text = DIALECTS[name].write(program, block_numbers=numbers)
        numpy = _read(monkeypatch, name, text, 10**12)
        assert _read(monkeypatch, name, text, 0) == numpy
        assert isinstance(numpy, str)


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_damaged_programs_fail_alike(name: str, data: st.DataObject) -> None:
    """Programs with edited lines (damaged numbers, words out of order, blanks, words no
    plain block has): the same program, or the same error (file, line, what was expected),
    compiled as by numpy."""
    lines = DIALECTS[name].write(_long_program(80), block_numbers=True).splitlines()
    edits = EDITS["heidenhain" if name == "heidenhain" else "gcode"]
    for _ in range(data.draw(st.integers(1, 5))):
        at = data.draw(st.integers(0, len(lines)))
        edit = data.draw(st.sampled_from(edits))
        if name == "heidenhain":
            edit = f"{at} {edit}" if data.draw(st.booleans()) else edit
        lines.insert(at, edit)
    text = "\n".join(lines) + "\n"
    with pytest.MonkeyPatch.context() as monkeypatch:
        numpy = _read(monkeypatch, name, text, 10**12)
        assert _read(monkeypatch, name, text, 0) == numpy


@pytest.mark.parametrize(
    ("name", "bad", "match"),
    [
        ("fanuc", "X1.2.3 Y1.", r"malformed number X1\.2\.3"),
        ("fanuc", "G1 X1. Q5. F100.", r"unknown word Q5\."),
        ("siemens", "Y1.2.3", r"malformed number Y1\.2\.3"),
        ("linuxcnc", "X1.5 U5", r"unknown word U5"),
        ("heidenhain", "L X+1.2.3 F300", r"malformed number X\+1\.2\.3"),
        ("heidenhain", "L X+1 Q5 FMAX", r"unknown word 'Q5' in L block"),
    ],
)
def test_errors_name_the_file_and_line(
    name: str, bad: str, match: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A damaged line among thousands of plain blocks read compiled: the error of the line by
    line reader, with the file and the line."""
    numbers = None if name == "heidenhain" else True
    lines = DIALECTS[name].write(_long_program(3_000), block_numbers=numbers).splitlines()
    at = 2_000
    lines[at] = f"{at} {bad}" if name == "heidenhain" else bad
    text = "\n".join(lines) + "\n"
    numpy = _read(monkeypatch, name, text, 10**12)
    assert isinstance(numpy, tuple)
    assert re.match(rf"^job:{at + 1}: .*{match}", numpy[1]), numpy
    assert _read(monkeypatch, name, text, 0) == numpy


# -- when it runs, and when it does not --------------------------------------------------------


def test_the_reader_reads_compiled_from_its_threshold(monkeypatch: pytest.MonkeyPatch) -> None:
    """A reader fed small pieces reads compiled once it has read COMPILED_FROM characters."""
    asked: list[bool] = []
    motion_lines = _bulk.motion_lines

    def spy(text: str, grammar: _bulk.MotionGrammar, **kwargs: bool) -> _bulk.MotionLines:
        asked.append(kwargs.get("compiled", False))
        return motion_lines(text, grammar, **kwargs)

    monkeypatch.setattr(_bulk, "motion_lines", spy)
    text = DIALECTS["fanuc"].write(_long_program(400), block_numbers=True)
    lines = text.splitlines(keepends=True)
    monkeypatch.setattr(reader_module, "COMPILED_FROM", len("".join(lines[:250])))
    reader = DIALECTS["fanuc"].reader("job")
    for start in range(0, len(lines), 100):
        reader.feed("".join(lines[start : start + 100]))
    assert asked == [False, False, True, True, True]


def test_without_numba_the_numpy_path_reads(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_bulk.KERNELS, "forced", False)
    text = DIALECTS["siemens"].write(_program("mm"), block_numbers=True)
    grammar = GRAMMARS["siemens"]
    assert compiled(text, grammar) is None
    assert_same(
        _bulk.motion_lines(text, grammar, compiled=True), reference_motion_lines(text, grammar)
    )


def test_the_numpy_path_reads_when_the_compiled_loop_fails(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture, stand_in: StandIn
) -> None:
    """numba that cannot compile or cache the loop here: a warning, and the numpy path reads
    (for the rest of the process too)."""

    def broken(*args: object) -> tuple:
        raise RuntimeError("cannot cache function 'read_lines': no locator available")

    stand_in(_bulk.KERNELS, SimpleNamespace(read_lines=broken))
    text = DIALECTS["heidenhain"].write(_program("mm"))
    grammar = GRAMMARS["heidenhain"]
    want = reference_motion_lines(text, grammar)
    with caplog.at_level(logging.WARNING, logger="urdfpost.dialects._bulk"):
        assert_same(_bulk.motion_lines(text, grammar, compiled=True), want)
    assert "compiled program reading unavailable (cannot cache function" in caplog.text
    assert _bulk.KERNELS.failed
    assert_same(_bulk.motion_lines(text, grammar, compiled=True), want)
    monkeypatch.setattr(reader_module, "COMPILED_FROM", 0)
    numpy = _outcome(lambda: repr(DIALECTS["heidenhain"].read(text)))
    monkeypatch.setattr(reader_module, "COMPILED_FROM", 10**12)
    assert _outcome(lambda: repr(DIALECTS["heidenhain"].read(text))) == numpy
