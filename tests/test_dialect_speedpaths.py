"""Speed paths of the dialects' bulk reading and writing (:mod:`urdfpost.dialects._bulk`).

The reader splits a text into words in pieces, and reads most pieces by a faster path than
the general one: the result must be that of the whole-text algorithm the pieces replaced (kept
here as :func:`reference_motion_lines`), bit for bit, for any text and any piece size. The
writer formats numbers in cells of four characters: the text must be that of
:meth:`NumberFormat.format`.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import urdfpost.dialects.writer as writer_module
from urdfpost.dialects import DIALECTS, _bulk
from urdfpost.dialects.reader import _grammar
from urdfpost.dialects.spec import NumberFormat
from urdfpost.program import Coolant, Move, Program, ToolChange

NAMES = sorted(DIALECTS)
FIELDS = ("starts", "ends", "plain", "axes", "code", "rapid_word", "feed")

# -- the reference: motion_lines on the whole text at once, as first written ------------------

_R_NUMBER, _R_CODE, _R_RAPID, _R_FEED = 0, 1, 8, 9
_R_AXES = {"X": 2, "Y": 3, "Z": 4, "A": 5, "B": 6, "C": 7}
_OTHER, _LETTER, _DIGIT, _POINT, _SIGN, _BLANK, _NEWLINE = range(7)
_CLASSES = bytearray([_OTHER] * 256)
for _c in range(65, 91):
    _CLASSES[_c] = _LETTER
for _c in range(48, 58):
    _CLASSES[_c] = _DIGIT
_CLASSES[46], _CLASSES[43], _CLASSES[45] = _POINT, _SIGN, _SIGN
_CLASSES[32], _CLASSES[10] = _BLANK, _NEWLINE
_CLASS_TABLE = bytes(_CLASSES)
_NO_LETTERS = bytes(32 if 65 <= c <= 90 else c for c in range(256))


def _keyword_at(b: np.ndarray, starts: np.ndarray, lengths: np.ndarray, word: str) -> np.ndarray:
    match = lengths == len(word)
    last = b.shape[0] - 1
    for i, char in enumerate(word.encode("ascii")):
        match &= b[np.minimum(starts + i, last)] == char
    return match


def reference_motion_lines(text: str, grammar: _bulk.MotionGrammar) -> tuple[np.ndarray, ...]:
    """The fields of :class:`MotionLines` as the whole-text algorithm gives them."""
    raw = text.encode("ascii", "replace")
    b = np.frombuffer(raw, dtype=np.uint8)
    cls = np.frombuffer(raw.translate(_CLASS_TABLE), dtype=np.uint8)
    n = b.shape[0]
    newline = cls == _NEWLINE
    ends = np.flatnonzero(newline)
    if n and not newline[-1]:
        ends = np.append(ends, n)
    starts = np.concatenate([[0], ends[:-1] + 1]).astype(np.int64)
    count = ends.shape[0]
    axes = np.full((count, 6), np.nan)
    code = np.full(count, -1, dtype=np.int8)
    rapid_word = np.zeros(count, dtype=bool)
    feed = np.full(count, np.nan)
    empty = (starts, ends, np.zeros(count, bool), axes, code, rapid_word, feed)
    if not count:
        return empty
    lengths = ends - starts
    plain = lengths > 0
    blank = cls == _BLANK
    separator = blank | newline
    odd = np.flatnonzero(cls == _OTHER)
    doubled = np.flatnonzero(blank[1:] & separator[:-1]) + 1
    trailing = np.flatnonzero(blank[:-1] & newline[1:])
    for positions in (odd, doubled, trailing):
        plain[np.searchsorted(starts, positions, side="right") - 1] = False
    plain &= ~blank[np.minimum(starts, n - 1)] & ~blank[np.maximum(ends - 1, 0)]
    inside = ~separator
    first = inside.copy()
    first[1:] &= separator[:-1]
    last = inside.copy()
    last[:-1] &= separator[1:]
    tokens = np.flatnonzero(first)
    if not tokens.size:
        return empty
    token_len = np.flatnonzero(last) + 1 - tokens
    line = np.searchsorted(starts, tokens, side="right") - 1
    owner_of = np.cumsum(first, dtype=np.int32) - 1

    def per_token(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        owner = owner_of[positions]
        return np.bincount(owner, minlength=tokens.shape[0]), owner

    head = b[tokens]
    head_letter = cls[tokens] == _LETTER
    letter = cls == _LETTER
    inner_letters, _ = per_token(np.flatnonzero(letter[1:] & inside[:-1]) + 1)
    letters = head_letter + inner_letters
    dots, _ = per_token(np.flatnonzero(cls == _POINT))
    sign_at = np.flatnonzero(cls == _SIGN)
    signs, sign_owner = per_token(sign_at)
    digits = token_len - letters - dots - signs
    misplaced = sign_at != tokens[sign_owner] + head_letter[sign_owner]
    sign_ok = np.ones(tokens.shape[0], dtype=bool)
    sign_ok[sign_owner[misplaced]] = False
    number_ok = (digits >= 1) & (dots <= 1) & (signs <= 1) & sign_ok
    word = head_letter & (letters == 1) & (token_len >= 2) & number_ok
    bare = ~head_letter & (letters == 0) & number_ok
    rank = np.full(tokens.shape[0], 99, dtype=np.int64)
    has_number = np.zeros(tokens.shape[0], dtype=bool)
    for address, r in _R_AXES.items():
        hit = word & (head == ord(address))
        if grammar.require_point:
            hit &= dots == 1
        rank[hit] = r
        has_number |= hit
    hit = word & (head == ord("F"))
    rank[hit] = _R_FEED
    has_number |= hit
    integer = (dots == 0) & (signs == 0)
    if grammar.number_letter:
        hit = word & (head == ord(grammar.number_letter)) & integer
    else:
        hit = bare & integer
    rank[hit] = _R_NUMBER
    has_number |= hit
    if grammar.codes:
        hit = word & (head == ord("G")) & (signs == 0)
        rank[hit] = _R_CODE
        has_number |= hit
    if grammar.lead:
        rank[_keyword_at(b, tokens, token_len, grammar.lead)] = _R_CODE
    if grammar.rapid_word:
        rank[_keyword_at(b, tokens, token_len, grammar.rapid_word)] = _R_RAPID
    bad_token = rank == 99
    same_line = line[1:] == line[:-1]
    bad_token[1:] |= same_line & (rank[1:] <= rank[:-1])
    plain &= np.bincount(line, weights=bad_token, minlength=count) == 0
    is_axis = (rank >= 2) & (rank <= 7)
    plain &= np.bincount(line, weights=is_axis, minlength=count) > 0
    if grammar.number_required:
        plain &= np.bincount(line, weights=rank == _R_NUMBER, minlength=count) > 0
    if grammar.lead:
        plain &= np.bincount(line, weights=rank == _R_CODE, minlength=count) > 0
    if not plain.any():
        return empty
    numbers = raw.translate(_NO_LETTERS)
    if not plain.all():
        kept = np.frombuffer(numbers, dtype=np.uint8).copy()
        kept[~np.repeat(plain, lengths + 1)[:n]] = 32
        numbers = kept.tobytes()
    values = np.fromstring(numbers, sep=" ")
    mine = has_number & plain[line]
    if values.shape[0] != int(mine.sum()):
        return empty
    value = np.full(tokens.shape[0], np.nan)
    value[mine] = values
    hit = mine & (rank >= 2) & (rank <= 7)
    axes[line[hit], rank[hit] - 2] = value[hit]
    hit = mine & (rank == _R_FEED)
    feed[line[hit]] = value[hit]
    plain[line[hit & ~(value > 0.0)]] = False
    if grammar.codes:
        hit = mine & (rank == _R_CODE)
        known = np.zeros(hit.shape, dtype=bool)
        for key, rapid in grammar.codes.items():
            match = hit & (value == key)
            code[line[match]] = 1 if rapid else 0
            known |= match
        plain[line[hit & ~known]] = False
    if grammar.rapid_word:
        hit = plain[line] & (rank == _R_RAPID)
        rapid_word[line[hit]] = True
    return starts, ends, plain, axes, code, rapid_word, feed


# -- comparing ----------------------------------------------------------------------------------

#: Grammars of the controls, and odd ones: no block number, keywords with digits and points
#: (whose lines the numbers read do not match: nothing is read in bulk, or the read fails).
GRAMMARS = {name: _grammar(DIALECTS[name].spec) for name in NAMES} | {
    "bare numbers": _bulk.MotionGrammar("", True, "L", {}, "FMAX", False),
    "codes": _bulk.MotionGrammar("N", False, None, {0.0: True, 1.0: False, 1.5: False}, None, True),
    "G numbers": _bulk.MotionGrammar("G", False, None, {0.0: True, 1.0: False}, None, False),
    "F numbers": _bulk.MotionGrammar("F", True, "L", {}, None, False),
    "lead with digits": _bulk.MotionGrammar("N", False, "L1", {}, None, False),
    "lead with points": _bulk.MotionGrammar("N", False, "L1.5.5", {}, None, False),
    "rapid word with digits": _bulk.MotionGrammar("N", False, None, {}, "R0", False),
}
#: Piece sizes: a line a piece, a few lines, and the whole text in one.
PIECES = (1, 2, 7, 64, 10**9)


def outcome(call):
    """The result of ``call``, or the type of the error it raised."""
    try:
        return call()
    except ValueError as exc:
        return type(exc)


def assert_same(got, want, where: object = None) -> None:
    """``got`` (MotionLines or an error type) is ``want`` (fields or an error type) bit for
    bit: dtypes, shapes, C order, every byte (NaN and -0.0 included)."""
    if isinstance(want, type):
        assert got is want, where
        return
    assert isinstance(got, _bulk.MotionLines), (where, got)
    for name, expected in zip(FIELDS, want, strict=True):
        array = getattr(got, name)
        assert array.dtype == expected.dtype, (where, name)
        assert array.shape == expected.shape, (where, name)
        assert array.flags.c_contiguous, (where, name)
        same = array.tobytes() == np.ascontiguousarray(expected).tobytes()
        assert same, (where, name)


def check_text(text: str, grammar: _bulk.MotionGrammar, pieces=PIECES) -> object:
    """Compare :func:`motion_lines` in pieces of each size with the reference."""
    want = outcome(lambda: reference_motion_lines(text, grammar))
    for piece in pieces:
        got = outcome(lambda piece=piece: _bulk.motion_lines(text, grammar, piece=piece))
        assert_same(got, want, (piece, text[:200]))
    return want


@pytest.fixture
def general_only(monkeypatch):
    """The general path only (the fast path declines every piece)."""
    monkeypatch.setattr(_bulk, "_fast_lines", lambda *args: None)


@pytest.fixture
def fast_only(monkeypatch):
    """Fail when a piece is not read by the fast path."""

    def refuse(*args):
        raise AssertionError("the general path read a piece")

    monkeypatch.setattr(_bulk, "_general_lines", refuse)


# -- written programs -------------------------------------------------------------------------


def _program(units: str, count: int = 600) -> Program:
    """Moves with every sign, signed zeros, long and short numbers, feed changes, rapids."""
    rng = np.random.default_rng(11)
    blocks: list = [ToolChange(4)]
    for k in range(count):
        scale = (1.0, 1e-3, 1e2, 1e4)[k % 4]
        x, y, z = rng.uniform(-1, 1, 3) * scale
        b, c = rng.uniform(-120, 120), rng.uniform(-400, 400)
        if k % 37 == 0:
            x, y = -0.0, 0.0004
        feed = None if k % 25 == 0 else float(100 * (1 + k // 97)) + (0.5 if k % 2 else 0.0)
        blocks.append(Move(k % 25 == 0, (x, y, z, b, c), feed))
        if k == count // 2:
            blocks.append(Coolant("flood"))
    return Program("P", ("X", "Y", "Z", "B", "C"), frozenset("BC"), units, False, tuple(blocks))


@pytest.mark.parametrize("units", ["mm", "inch"])
@pytest.mark.parametrize("block_numbers", [None, True])
@pytest.mark.parametrize("name", NAMES)
def test_written_programs_read_alike_in_any_pieces(name, block_numbers, units, fast_only):
    text = DIALECTS[name].write(_program(units), block_numbers=block_numbers)
    want = check_text(text, GRAMMARS[name], pieces=(1, 3, 100, 4096, _bulk.MOTION_PIECE))
    assert want[2].sum() > 500  # the moves are plain motion blocks


@pytest.mark.parametrize("name", NAMES)
def test_general_path_reads_written_programs_alike(name, general_only):
    text = DIALECTS[name].write(_program("mm"), block_numbers=True)
    want = check_text(text, GRAMMARS[name], pieces=(5, 10**9))
    assert want[2].sum() > 500


# -- nasty texts ------------------------------------------------------------------------------

NASTY = [
    "",
    "\n",
    "\n\n\n",
    "X1",
    "X1\n",
    "X1.\n\nY2.\n",
    "G1 X1.\n\nG0 Y2.",
    "N10 G1 X1. Y-2.5 Z+.5 F500.\nN20 X1.5\nN30 Y-0.\n",
    "5 L X+1.000 Y-2.000 FMAX\n6 L Z+3.000 F250\n7 L B+0.0000\n",
    "L X+1 Y+2 Z+3 A+4 B+5 C+6",
    "; a comment only\n(another)\n%\n",
    "G1 X1. (note)\nG1 X2. ; note\nX3.\n",
    " X1\nX1 \nX1  Y2\nX1\tY2\n X\n",
    "X1\nX2 ",
    " X1",
    "X1.2.3\nX+-1\nX1+\nX-\nX.\nX+.\nX.5\nX5.\nX+.5 Y-.0 Z-0.000 A+0\n",
    "x1\nG1 x1.\nX١.\nXé1\n",
    "G1.5 X1\nG2 X1\nG-0 X1\nG01 X1\nG1.0 X1\nG0 X1 G1\n",
    "N1 G1 X1 F0\nN2 G1 X1 F0.0\nN3 G1 X1 F-1\nN4 G1 X1 F.5\n",
    "L X+1 FMAX F300\nL X+1 F300 FMAX\nL FMAX\nFMAX X1\nL X+1 R0\n",
    "X123456789012345\nX1234567890123456\nX12345678.9012345\nX1234567890123.456\n",
    "X0.000000000000001 Y-0.00000000000000\nZ" + "9" * 400 + "\n",
    "N1 X1\n" * 50 + "N" + "1" * 70 + " X1.25",
    "L1 X1\nL X1\nL1 X2.5\n",
    "L1.5.5 X1\nL X1\n",
    "X1\r\nY2\r\n",
    "X1\x0cY2\n",
    "\n".join(f"N{k} X{k % 7 - 3}.{k:03d} Y-{k}.5 F{k % 3 + 1}00" for k in range(300)),
]


@pytest.mark.parametrize("grammar", sorted(GRAMMARS))
@pytest.mark.parametrize("text", NASTY, ids=range(len(NASTY)))
def test_nasty_texts_read_alike_in_any_pieces(text, grammar):
    check_text(text, GRAMMARS[grammar])


@pytest.mark.parametrize("grammar", sorted(GRAMMARS))
@pytest.mark.parametrize("text", NASTY, ids=range(len(NASTY)))
def test_nasty_texts_read_alike_by_the_general_path(text, grammar, general_only):
    check_text(text, GRAMMARS[grammar], pieces=(3, 10**9))


def test_lines_longer_than_a_piece():
    long_line = "N1 " + " ".join(["X1.5"] * 3000)  # not plain: X twice
    text = f"N1 X1.\n{long_line}\nN2 Y2.\n{'N3 Z3.' + ' ' * 5000}\nN4 Z4."
    for grammar in GRAMMARS.values():
        check_text(text, grammar, pieces=(1, 16, 1000, 10**9))


def test_odd_grammars_read_nothing_or_fail_like_the_reference():
    """Numbers that do not match the words: no line plain (even those of the pieces whose
    numbers match), or the read fails (in whichever piece)."""
    want = check_text("X1\nL1 X1\nL1 X2.5\n", GRAMMARS["lead with digits"])
    assert not want[2].any()
    text = "X1\nX2\nX3 R0\nX4\n" * 5
    assert GRAMMARS["rapid word with digits"].rapid_word == "R0"
    assert check_text(text.replace(" R0", ""), GRAMMARS["rapid word with digits"])[2].all()
    assert not check_text(text, GRAMMARS["rapid word with digits"])[2].any()
    assert check_text("X2\nL1.5.5 X1\n", GRAMMARS["lead with points"]) is ValueError
    assert check_text("L1.5.5 X1\n" + "X2\n" * 40, GRAMMARS["lead with points"]) is ValueError


LINE_WORDS = st.sampled_from(
    ["N12", "12", "G0", "G1", "G1.5", "G01", "L", "FMAX", "R0", "F0", "F250", "F.5", "F-1", "M3"]
    + [f"{a}{n}" for a in "XYZABC" for n in ("1", "-2.5", "+.5", "5.", "-0", "0.000")]
    + ["X1.2.3", "X+-1", "1e5", "x1", ";", "(c)", "X9999999999999999", "Xé"]
)


@st.composite
def texts(draw: st.DrawFn) -> str:
    lines = []
    for _ in range(draw(st.integers(0, 30))):
        words = draw(st.lists(LINE_WORDS, max_size=7))
        separator = draw(st.sampled_from([" ", " ", " ", "  ", ""]))
        line = separator.join(words)
        lines.append(draw(st.sampled_from(["", " "])) + line + draw(st.sampled_from(["", " "])))
    return "\n".join(lines) + draw(st.sampled_from(["", "\n", "\n\n"]))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(text=texts(), grammar=st.sampled_from(sorted(GRAMMARS)), piece=st.integers(1, 200))
def test_random_texts_read_alike_in_any_pieces(text, grammar, piece):
    check_text(text, GRAMMARS[grammar], pieces=(piece, 10**9))


# -- writing ----------------------------------------------------------------------------------


def _formats() -> list[NumberFormat]:
    return [
        NumberFormat(decimals, plus_sign=plus, trim=trim, point=point)
        for decimals in range(16)
        for plus in (False, True)
        for trim in (False, True)
        for point in (False, True)
    ]


@pytest.mark.parametrize("fmt", _formats(), ids=repr)
def test_number_cells_write_what_number_format_writes(fmt):
    rng = np.random.default_rng(5)
    values = [0.0, -0.0, 5e-324, 0.5, -0.5, 1.0, 10.0, 100.0, 999.0, 1000.0, 9999.5, 10000.0]
    values += [-1e5, 123456.0, 1e9, -(0.1 + 0.2)]
    for scale in (1e-3, 1.0, 1e3, 1e6, 1e12):
        values += list(rng.uniform(-scale, scale, 60))
        values += list(np.round(rng.uniform(-scale, scale, 30), min(fmt.decimals, 6)))
    values = np.array([v for v in values if abs(v) * 10.0**fmt.decimals < _bulk.MAX_SCALED])
    scaled = _bulk.scaled_integers(values, fmt.decimals)
    assert scaled is not None
    newline = _bulk.repeated_cells("\n", values.size)
    for head in ("", " X", " AB", " ABC", " ABCD", " ABCDEF"):
        cells = _bulk.number_cells(scaled, values < 0, fmt, head)
        text = _bulk.text_of_cells(np.concatenate([cells, newline]))
        assert text.splitlines() == [head + fmt.format(float(v)) for v in values]


def test_integer_cells():
    numbers = np.array([0, 7, 10, 9999, 10_000, 10_001, 123_456_789, 10**15, 10**16 - 1])
    newline = _bulk.repeated_cells("\n", numbers.size)
    text = _bulk.text_of_cells(np.concatenate([_bulk.integer_cells(numbers), newline]))
    assert text.splitlines() == [str(n) for n in numbers]
    text = _bulk.text_of_cells(np.concatenate([_bulk.integer_cells(numbers, zero=False), newline]))
    assert text.splitlines() == ["" if n == 0 else str(n) for n in numbers]
    assert _bulk.integer_cells(np.zeros(3, dtype=np.int64), zero=False).shape == (0, 3)
    slots = _bulk.integer_slots(numbers)
    assert [bytes(row[row != 0]).decode() for row in slots] == [str(n) for n in numbers]


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("units", ["mm", "inch"])
def test_bulk_write_of_many_chunks_equals_block_by_block(name, units, monkeypatch):
    """More moves than a chunk of the bulk writer, feeds changing, big and signed zero values."""
    program = _program(units, count=2 * writer_module._BULK_ROWS + 321)
    numbers = None if name == "heidenhain" else True
    texts = []
    for least in (2, 10**9):
        monkeypatch.setattr(writer_module, "BULK_MIN_MOVES", least)
        texts.append(DIALECTS[name].write(program, block_numbers=numbers).splitlines())
    assert len(texts[0]) == len(texts[1])
    differ = [(a, b) for a, b in zip(*texts, strict=True) if a != b]
    assert not differ, differ[:3]  # (a long text's diff would take pytest minutes)
