"""Many motion blocks at once: their text for the writer, their words for the reader.

The writer's side builds the lines of many blocks as columns of a matrix of cells, four
characters in one uint32 (NUL where a line has nothing there), each word in rows of its own;
the text is the transposed matrix with the NUL bytes taken out. A number's text is computed
from its value scaled to an integer, four digits at once from a table, which gives exactly the
text of :meth:`~urdfpost.dialects.spec.NumberFormat.format`: the integer is the correctly
rounded value (as Python's ``f"{value:.3f}"`` rounds it) everywhere except within a hair of a
rounding tie, where Python's own formatting gives it.

The reader's side (:func:`motion_lines`) splits the lines of a text into words with array
operations, in pieces that keep the arrays in the processor's cache, checks which lines are
plain motion blocks, and reads all their numbers with one call of ``np.fromstring`` a piece:
as integers without their points, then divided by a power of ten, which is the ``float`` of
the text (bit for bit) for up to 15 digits; as ``float`` reads them otherwise. Asked to run
compiled (large texts, with numba installed), it is one loop over the bytes
(:mod:`urdfpost.dialects._line_kernel`) with the same result.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from types import ModuleType

import numpy as np

from urdfpost._compiled import Kernels
from urdfpost.dialects.spec import NumberFormat

log = logging.getLogger(__name__)

#: Largest scaled value formatted here (beyond, the caller writes the values one by one).
MAX_SCALED = 2.0**52

_ZERO, _POINT, _MINUS, _PLUS = 48, 46, 45, 43


def scaled_integers(values: np.ndarray, decimals: int) -> np.ndarray | None:
    """``values`` times ``10**decimals`` rounded as Python's fixed-point formatting rounds.

    Parameters
    ----------
    values : ndarray, shape (k,)
        Finite numbers.
    decimals : int
        Digits after the decimal point (0 to 15).

    Returns
    -------
    ndarray, shape (k,), int64, or None
        Signed integers (the text's digits); None when a value is too large for them.
    """
    scaled = values * 10.0**decimals
    if values.size and not np.abs(scaled).max() < MAX_SCALED:
        return None
    rounded = np.rint(scaled)
    # the product is within half an ulp of the exact one: only near a tie may the exact value
    # round the other way (or be an exact tie, which Python rounds to even, as rint does)
    near_tie = np.abs(np.abs(scaled - rounded) - 0.5) <= 1e-9 * np.maximum(np.abs(scaled), 1.0)
    out = rounded.astype(np.int64)
    for k in np.flatnonzero(near_tie):
        text = f"{float(values[k]):.{decimals}f}"
        out[k] = int(text.replace(".", ""))
    return out


# -- cells: four characters of a text in one uint32 ------------------------------------------

#: Shift of the character at position 0 to 3 of a cell (a cell is four bytes of the text).
_SHIFTS = (0, 8, 16, 24) if sys.byteorder == "little" else (24, 16, 8, 0)
_DIGITS = np.arange(10_000)[:, None] // np.array([1000, 100, 10, 1]) % 10 + _ZERO
#: The cells of 0000 to 9999, and the same without leading zeros (NUL instead, "0" for 0).
_FOUR_DIGITS = _DIGITS.astype(np.uint8).view(np.uint32).reshape(-1)
_FOUR_DIGITS_BARE = (
    np.where(np.arange(10_000)[:, None] < [1000, 100, 10, 0], 0, _DIGITS)
    .astype(np.uint8)
    .view(np.uint32)
    .reshape(-1)
)


#: Every character of a cell.
_ALL = np.uint32(0xFFFFFFFF)


def character_mask(*positions: int) -> np.uint32:
    """The bits of the characters at ``positions`` (0 to 3) of a cell."""
    return np.uint32(sum(0xFF << _SHIFTS[p] for p in positions))


def _earlier(cells: np.ndarray, positions: int) -> np.ndarray:
    """Cells with their characters moved ``positions`` places towards the start (the first
    ones dropped, NUL at the end)."""
    return cells >> 8 * positions if sys.byteorder == "little" else cells << 8 * positions


def text_cells(text: str) -> np.ndarray:
    """An ASCII text in cells, NUL-padded, shape (c,), uint32."""
    raw = text.encode("ascii")
    return np.frombuffer(raw + b"\0" * (-len(raw) % 4), dtype=np.uint32).copy()


def repeated_cells(text: str, k: int) -> np.ndarray:
    """The same ASCII text in ``k`` columns of cells, shape (c, k)."""
    return np.repeat(text_cells(text)[:, None], k, axis=1)


def text_of_cells(matrix: np.ndarray) -> str:
    """The texts of the columns of a matrix of cells, shape (c, k), without the NUL bytes,
    concatenated."""
    return matrix.T.tobytes().translate(None, b"\0").decode("ascii")


def _slots(cells: np.ndarray) -> np.ndarray:
    """The texts of the columns of cells as rows of a byte matrix, shape (k, 4 c)."""
    return np.ascontiguousarray(cells.T).view(np.uint8)


def integer_cells(numbers: np.ndarray, zero: bool = True) -> np.ndarray:
    """Text of non-negative integers in cells, right-aligned, NUL-padded.

    Parameters
    ----------
    numbers : ndarray, shape (k,), int
    zero : bool
        Write 0 as "0" (else as nothing: no cell at all when every number is 0).

    Returns
    -------
    ndarray, shape (c, k), uint32
    """
    top = int(numbers.max()) if numbers.size else 0
    groups = -(-len(str(top)) // 4) if top or zero else 0
    out = np.empty((groups, numbers.shape[0]), dtype=np.uint32)
    rest = numbers
    for g in range(groups - 1, -1, -1):
        quotient = rest // 10_000
        low = rest - quotient * 10_000
        rest = quotient
        bare = _FOUR_DIGITS_BARE[low]  # in the group of the first digit
        if g == groups - 1 and zero:
            out[g] = bare
        else:
            out[g] = np.where(numbers >= 10 ** (4 * (groups - 1 - g)), bare, 0)
        if g:
            out[g] = np.where(numbers >= 10 ** (4 * (groups - g)), _FOUR_DIGITS[low], out[g])
    return out


def integer_slots(numbers: np.ndarray) -> np.ndarray:
    """Text of non-negative integers, right-aligned in NUL-padded slots, shape (k, width)."""
    return _slots(integer_cells(numbers))


def number_cells(
    scaled: np.ndarray, negative: np.ndarray, fmt: NumberFormat, head: str = ""
) -> np.ndarray:
    """``head`` then the text of fixed-point numbers as ``fmt`` writes them, in cells.

    The point and the decimals fill the last cells; the first of them starts with the last
    digits of the integer part when the point and the decimals are not a multiple of four
    characters: with ``head`` "X", ``X+12.3456`` is the cells ``X+__``, ``_12.`` and
    ``3456`` (``_`` for NUL).

    Parameters
    ----------
    scaled : ndarray, shape (k,), int64
        The value times ``10**fmt.decimals``, rounded (see :func:`scaled_integers`).
    negative : ndarray, shape (k,), bool
        Whether the value is below zero (a zero text never gets a minus sign).
    fmt : NumberFormat
    head : str
        ASCII text before each number (e.g. ``" X"``).

    Returns
    -------
    ndarray, shape (c, k), uint32
        The texts' characters, NUL where a text has nothing.
    """
    k = scaled.shape[0]
    d = fmt.decimals
    magnitude = np.abs(scaled)
    sign = np.where((scaled != 0) & negative, _MINUS, _PLUS if fmt.plus_sign else 0)
    sign = sign.astype(np.uint32)
    cells = [repeated_cells(head, k)]
    if len(head) % 4:
        cells[0][-1] |= sign << _SHIFTS[len(head) % 4]
    else:
        cells.append((sign << _SHIFTS[0])[None, :])
    if d == 0:
        cells.append(integer_cells(magnitude))
        if fmt.point:
            cells.append(repeated_cells(".", k))
        return np.concatenate(cells)
    shared = -(d + 1) % 4  # integer digits in the cell of the point
    after = 3 - shared  # decimals in the cell of the point
    whole = magnitude // 10**d
    fraction = magnitude - whole * 10**d
    high = whole // 10**shared
    low = whole - high * 10**shared
    cells.append(integer_cells(high, zero=shared == 0))
    # the cell of the point: the last integer digits (but leading zeros), the point and the
    # first decimals
    rest = d - after  # decimals in the last cells, a multiple of four
    first = fraction // 10**rest
    point = _FOUR_DIGITS[first] & character_mask(*range(4 - after, 4))
    point |= np.uint32(_POINT << _SHIFTS[shared])
    if shared:
        digits = np.where(whole >= 10**shared, _FOUR_DIGITS[low], _FOUR_DIGITS_BARE[low])
        point |= _earlier(digits, 4 - shared)
    fraction = fraction - first * 10**rest
    decimals = np.empty((rest // 4 + 1, k), dtype=np.uint32)
    decimals[0] = point
    for g in range(rest // 4, 0, -1):
        quotient = fraction // 10_000
        decimals[g] = _FOUR_DIGITS[fraction - quotient * 10_000]
        fraction = quotient
    if fmt.trim:
        # keep the decimals up to the last non-zero one; the point when any is kept
        kept = np.zeros(k, dtype=bool)
        places = [(0, p) for p in range(4 - after, 4)]
        places += [(g, p) for g in range(1, rest // 4 + 1) for p in range(4)]
        for g, p in reversed(places):
            kept |= (decimals[g] >> _SHIFTS[p]) & 0xFF != _ZERO
            decimals[g] &= np.where(kept, _ALL, ~character_mask(p))
        if not fmt.point:
            decimals[0] &= np.where(kept, _ALL, ~character_mask(shared))
    cells.append(decimals)
    return np.concatenate(cells)


def number_slots(scaled: np.ndarray, negative: np.ndarray, fmt: NumberFormat) -> np.ndarray:
    """Text of fixed-point numbers as ``fmt`` writes them, in NUL-padded slots.

    Parameters
    ----------
    scaled, negative, fmt
        As for :func:`number_cells`.

    Returns
    -------
    ndarray, shape (k, width), uint8
        Sign, integer digits, point and decimals; NUL where the text has nothing.
    """
    return _slots(number_cells(scaled, negative, fmt))


def text_of_rows(matrix: np.ndarray) -> str:
    """The rows of a NUL-padded byte matrix without the NUL bytes, concatenated."""
    flat = matrix.reshape(-1)
    return flat[flat != 0].tobytes().decode("ascii")


# -- reading ---------------------------------------------------------------------------------

#: Rank of each word in a plain motion block: block number, lead or motion code, the axes in
#: AXIS_ORDER, the rapid word, the feed. A block's words come in increasing rank.
_RANK_NUMBER, _RANK_CODE, _RANK_RAPID, _RANK_FEED = 0, 1, 8, 9
_AXIS_RANKS = {"X": 2, "Y": 3, "Z": 4, "A": 5, "B": 6, "C": 7}
#: Rank of a word no plain block has.
_UNKNOWN = 99
#: Rank of the axis word of each letter (0 for no axis letter).
_AXIS_RANK_OF = np.zeros(256, dtype=np.int64)
for _address, _rank in _AXIS_RANKS.items():
    _AXIS_RANK_OF[ord(_address)] = _rank

#: Character classes of the bytes of a plain motion block; everything else is _OTHER. The
#: order matters: _LETTER to _NEWLINE are the characters the fast path locates one by one,
#: _NEWLINE and _BLANK separate words.
_OTHER, _DIGIT, _LETTER, _POINT_CLASS, _SIGN, _NEWLINE, _BLANK = range(7)
_CLASSES = bytearray([_OTHER] * 256)
for _code in range(65, 91):
    _CLASSES[_code] = _LETTER
for _code in range(48, 58):
    _CLASSES[_code] = _DIGIT
_CLASSES[46], _CLASSES[43], _CLASSES[45] = _POINT_CLASS, _SIGN, _SIGN
_CLASSES[32], _CLASSES[10] = _BLANK, _NEWLINE
_CLASS_TABLE = bytes(_CLASSES)
#: The bytes with letters turned into blanks (what is left of a word is its number).
_NO_LETTERS = bytes(32 if 65 <= c <= 90 else c for c in range(256))
_LINE_BREAK, _MINUS_BYTE = 10, 45

#: Characters of text split into words at once by :func:`motion_lines`: small enough for its
#: temporary arrays (some 20 bytes a character) to stay in the processor's cache.
MOTION_PIECE = 1 << 18
#: Most digits of a number the fast path reads as an integer (below 2**53: exact in a float).
_MAX_DIGITS = 15
#: ``10.0**k`` for the decimals of those numbers, exact.
_POWERS_OF_TEN = np.array([float(10**k) for k in range(_MAX_DIGITS + 1)])
#: Bits of each count packed in one int64 by the fast path (inner letters, points, signs,
#: line breaks after a word).
_FIELD_BITS = 16


@dataclass(frozen=True)
class MotionGrammar:
    """Which plain motion blocks a control's reader may read in bulk.

    A plain block is, separated by single blanks and in this order: the block number
    (``number_letter`` then digits, e.g. ``N120``, or digits alone when ``number_letter`` is
    ""; required when ``number_required``), the ``lead`` word or a motion code ``G<code>``
    whose value is a key of ``codes``, axis words ``X+1.5`` (at least one, each axis once,
    X Y Z A B C order), the ``rapid_word``, and a feed word ``F500``. Upper case ASCII only,
    numbers as the readers accept them.

    Attributes
    ----------
    number_letter : str
    number_required : bool
    lead : str or None
    codes : mapping of float to bool
        Motion code value -> rapid (``{0.0: True, 1.0: False}``); empty without codes.
    rapid_word : str or None
    require_point : bool
        Axis values must have a decimal point.
    """

    number_letter: str
    number_required: bool
    lead: str | None
    codes: Mapping[float, bool]
    rapid_word: str | None
    require_point: bool


@dataclass(frozen=True)
class MotionLines:
    """The plain motion blocks among the lines of a text (see :func:`motion_lines`).

    Attributes
    ----------
    starts, ends : ndarray, shape (L,), int
        Offsets of each line in the text (``ends`` at its line break or the text's end).
    plain : ndarray, shape (L,), bool
        Which lines are plain motion blocks; the fields below are defined for them.
    axes : ndarray, shape (L, 6)
        Axis values as written, X Y Z A B C; NaN where the block has no such word.
    code : ndarray, shape (L,)
        Rapid (1), linear (0) from the motion code, or -1 without code.
    rapid_word : ndarray, shape (L,), bool
        Whether the block has the rapid word.
    feed : ndarray, shape (L,)
        Feed word value as written, NaN without.
    """

    starts: np.ndarray
    ends: np.ndarray
    plain: np.ndarray
    axes: np.ndarray
    code: np.ndarray
    rapid_word: np.ndarray
    feed: np.ndarray


class _Unread(Exception):
    """The numbers of the plain lines did not read as expected (no line is read in bulk)."""


def _no_motion(starts: np.ndarray, ends: np.ndarray) -> MotionLines:
    """Lines none of which is a plain motion block."""
    count = ends.shape[0]
    return MotionLines(
        starts,
        ends,
        np.zeros(count, dtype=bool),
        np.full((count, 6), np.nan),
        np.full(count, -1, dtype=np.int8),
        np.zeros(count, dtype=bool),
        np.full(count, np.nan),
    )


def motion_lines(
    text: str, grammar: MotionGrammar, piece: int = MOTION_PIECE, compiled: bool = False
) -> MotionLines:
    """Find and read the plain motion blocks among the lines of ``text``, all at once.

    The text is split into words in pieces of about ``piece`` characters cut at line breaks;
    the result does not depend on ``piece``. With ``compiled`` (and numba installed), the
    text is read by the compiled loop of :mod:`urdfpost.dialects._line_kernel` instead, with
    the same result; it falls back to the numpy path where it cannot (a grammar whose keywords
    are not letters only, a plain block with a number of more than 15 digits, numba missing
    or failing here).

    Parameters
    ----------
    text : str
        Lines separated by ``\\n`` only.
    grammar : MotionGrammar
    piece : int
        Characters split at once (at least; a piece ends at a line break).
    compiled : bool
        Read by the compiled loop when it can (worth it for large texts only: numba's import
        and the loading of its machine code take some 0.4 to 0.9 s once per process).

    Returns
    -------
    MotionLines
        Numbers are read as ``float`` reads them (bit for bit).
    """
    raw = text.encode("ascii", "replace")
    n = len(raw)
    if not n:
        return _general_lines(raw, grammar)
    fast = _letters_only(grammar.lead) and _letters_only(grammar.rapid_word)
    if compiled and fast:
        read = _compiled_lines(raw, grammar)
        if read is not None:
            return read
    ends = np.flatnonzero(np.frombuffer(raw, dtype=np.uint8) == _LINE_BREAK)
    if raw[-1] != _LINE_BREAK:
        ends = np.append(ends, n)
    starts = np.concatenate([[0], ends[:-1] + 1]).astype(np.int64)
    out = _no_motion(starts, ends)
    count = ends.shape[0]
    unread = False
    row = 0
    while row < count:
        begin = int(starts[row])
        stop = min(int(np.searchsorted(ends, begin + max(piece, 1) - 1)) + 1, count)
        lines = slice(row, stop)
        text_piece = raw[begin : int(ends[stop - 1]) + 1]
        part = None
        try:
            if fast:
                part = _fast_lines(text_piece, grammar, starts[lines] - begin, ends[lines] - begin)
            if part is None:
                part = _general_lines(text_piece, grammar)
        except _Unread:  # like one piece: nothing is read, errors are raised
            unread = True
            row = stop
            continue
        out.plain[lines] = part.plain
        out.axes[lines] = part.axes
        out.code[lines] = part.code
        out.rapid_word[lines] = part.rapid_word
        out.feed[lines] = part.feed
        row = stop
    return _no_motion(starts, ends) if unread else out


def _load_kernel() -> ModuleType:
    from urdfpost.dialects import _line_kernel

    return _line_kernel


KERNELS = Kernels(_load_kernel, "program reading", logger=log)
"""The compiled loop (:mod:`urdfpost.dialects._line_kernel`), loaded by :func:`motion_lines`
when it is asked to read compiled (the reader decides from the size of its text)."""


def _word_bytes(word: str | None) -> np.ndarray:
    """A keyword's bytes, shape (k,), uint8 (empty for none)."""
    return np.frombuffer((word or "").encode("ascii"), dtype=np.uint8)


def _compiled_lines(raw: bytes, grammar: MotionGrammar) -> MotionLines | None:
    """:func:`motion_lines` of a text (ASCII bytes, not empty) by the compiled loop, or None
    where it does not read it (numba missing or failing here, a number of more than 15
    digits in a plain block)."""
    kernel = KERNELS.load()
    if kernel is None:
        return None
    keys = np.array(list(grammar.codes), dtype=float)
    rapid = np.array(list(grammar.codes.values()), dtype=bool)
    try:
        *fields, status = kernel.read_lines(
            np.frombuffer(raw, dtype=np.uint8),
            raw.count(b"\n"),
            ord(grammar.number_letter) if grammar.number_letter else -1,
            grammar.number_required,
            _word_bytes(grammar.lead),
            keys,
            rapid,
            _word_bytes(grammar.rapid_word),
            grammar.require_point,
        )
    except Exception as e:  # numba could not compile or cache it here: the numpy path
        KERNELS.fail(e)
        return None
    if status:
        return None
    return MotionLines(*fields)


def _letters_only(word: str | None) -> bool:
    """Whether a keyword of the grammar is absent or upper case ASCII letters only."""
    return not word or (word.isascii() and word.isalpha() and word.isupper())


def _line_of(starts: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Line (index into ``starts``) of each offset in ``positions``."""
    return np.searchsorted(starts, positions, side="right") - 1


def _keyword_at(
    b: np.ndarray, starts: np.ndarray, lengths: np.ndarray, head: np.ndarray, word: str
) -> np.ndarray:
    """Which tokens (start offsets, lengths, first bytes) of the byte array are exactly
    ``word`` (not empty)."""
    chars = word.encode("ascii")
    match = (lengths == len(chars)) & (head == chars[0])
    if len(chars) > 1:
        candidates = np.flatnonzero(match)
        at = starts[candidates]
        same = np.ones(candidates.shape[0], dtype=bool)
        for i, char in enumerate(chars[1:], start=1):
            same &= b[at + i] == char
        match[candidates[~same]] = False
    return match


def _token_ranks(
    grammar: MotionGrammar,
    b: np.ndarray,
    tokens: np.ndarray,
    token_len: np.ndarray,
    word: np.ndarray,
    bare: np.ndarray,
    dots: np.ndarray,
    signs: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Rank of each token in a plain block (``_UNKNOWN`` for no word of one), and whether the
    token is read as a number.

    Parameters
    ----------
    grammar : MotionGrammar
    b : ndarray, uint8
        The text.
    tokens, token_len : ndarray, shape (T,), int
        Offset and length of each token.
    word, bare : ndarray, shape (T,), bool
        Whether the token is a letter and a number, or a number alone.
    dots, signs : ndarray, shape (T,), int
        Points and signs in each token.

    Returns
    -------
    rank : ndarray, shape (T,), int64
    has_number : ndarray, shape (T,), bool
    """
    head = b[tokens]
    axis_rank = _AXIS_RANK_OF[head]
    has_number = word & (axis_rank > 0)
    if grammar.require_point:
        has_number &= dots == 1
    rank = np.where(has_number, axis_rank, _UNKNOWN)
    hit = word & (head == ord("F"))
    rank[hit] = _RANK_FEED
    has_number |= hit
    integer = (dots == 0) & (signs == 0)
    if grammar.number_letter:
        hit = word & (head == ord(grammar.number_letter)) & integer
    else:
        hit = bare & integer
    rank[hit] = _RANK_NUMBER
    has_number |= hit
    if grammar.codes:
        hit = word & (head == ord("G")) & (signs == 0)  # G-0 is no code, G0 is
        rank[hit] = _RANK_CODE
        has_number |= hit
    if grammar.lead:
        rank[_keyword_at(b, tokens, token_len, head, grammar.lead)] = _RANK_CODE
    if grammar.rapid_word:
        rank[_keyword_at(b, tokens, token_len, head, grammar.rapid_word)] = _RANK_RAPID
    return rank, has_number


def _check_lines(
    grammar: MotionGrammar, plain: np.ndarray, line: np.ndarray, rank: np.ndarray
) -> None:
    """Keep as plain the lines whose tokens are known, in increasing rank, with an axis word
    (and the block number and lead when the grammar requires them); in place.

    Parameters
    ----------
    grammar : MotionGrammar
    plain : ndarray, shape (L,), bool
    line : ndarray, shape (T,), int
        Line of each token, non-decreasing.
    rank : ndarray, shape (T,), int
        Rank of each token.
    """
    bad_token = rank == _UNKNOWN
    bad_token[1:] |= (line[1:] == line[:-1]) & (rank[1:] <= rank[:-1])
    # what the tokens of each line (with any) have: bit 0 a bad token, 1 an axis, 2 a block
    # number, 3 a lead or motion code
    flags = bad_token.view(np.uint8).copy()
    flags |= ((rank >= 2) & (rank <= 7)).view(np.uint8) << 1
    required = 2
    if grammar.number_required:
        flags |= (rank == _RANK_NUMBER).view(np.uint8) << 2
        required |= 4
    if grammar.lead:
        flags |= (rank == _RANK_CODE).view(np.uint8) << 3
        required |= 8
    first = np.concatenate([[0], np.flatnonzero(line[1:] != line[:-1]) + 1])  # of each line
    found = np.bitwise_or.reduceat(flags, first)
    keep = np.zeros(plain.shape[0], dtype=bool)
    keep[line[first]] = (found & (required | 1)) == required
    plain &= keep


def _store_values(
    grammar: MotionGrammar,
    lines: MotionLines,
    line: np.ndarray,
    rank: np.ndarray,
    read: np.ndarray,
    values: np.ndarray,
) -> MotionLines:
    """The lines with the numbers read in their axes, feeds and codes, and their rapid words;
    lines with a feed of zero or an unknown code are no longer plain.

    Parameters
    ----------
    grammar : MotionGrammar
    lines : MotionLines
        Of the text (all lines), with no word read; ``plain`` as checked so far (updated).
    line, rank : ndarray, shape (T,), int
        Line and rank of each token.
    read : ndarray, shape (R,), int
        The tokens whose numbers were read (those with one in the plain lines), in order.
    values : ndarray, shape (R,)
        Their numbers.

    Returns
    -------
    MotionLines
    """
    plain = lines.plain
    words = np.full((plain.shape[0], _RANK_FEED + 1), np.nan)  # the number of each rank
    words.reshape(-1)[line[read] * (_RANK_FEED + 1) + rank[read]] = values
    feed = words[:, _RANK_FEED]
    plain &= ~(feed <= 0.0)  # the reader refuses F0
    if grammar.codes:
        value = words[:, _RANK_CODE]
        known = np.zeros(plain.shape, dtype=bool)
        for key, rapid in grammar.codes.items():
            match = value == key
            lines.code[match] = 1 if rapid else 0
            known |= match
        plain &= known | np.isnan(value)
    if grammar.rapid_word:
        rapid = line[rank == _RANK_RAPID]
        lines.rapid_word[rapid] = plain[rapid]
    return MotionLines(
        lines.starts, lines.ends, plain, words[:, 2:8], lines.code, lines.rapid_word, feed
    )


def _numbers_text(raw: bytes, lines: MotionLines, delete: bytes) -> bytes:
    """The text with letters and ``delete`` taken out, blank but in the plain lines."""
    if lines.plain.all():
        return raw.translate(_NO_LETTERS, delete)
    kept = np.frombuffer(raw.translate(_NO_LETTERS), dtype=np.uint8).copy()
    kept[~np.repeat(lines.plain, lines.ends - lines.starts + 1)[: kept.shape[0]]] = 32
    return kept.tobytes().translate(None, delete)


def _general_lines(raw: bytes, grammar: MotionGrammar) -> MotionLines:
    """:func:`motion_lines` of one piece of text (ASCII bytes), for any text and grammar.

    Raises
    ------
    _Unread
        The numbers read are not one for each number word of the plain lines.
    """
    b = np.frombuffer(raw, dtype=np.uint8)
    cls = np.frombuffer(raw.translate(_CLASS_TABLE), dtype=np.uint8)
    n = b.shape[0]
    newline = cls == _NEWLINE
    ends = np.flatnonzero(newline)
    if n and not newline[-1]:
        ends = np.append(ends, n)
    starts = np.concatenate([[0], ends[:-1] + 1]).astype(np.int64)
    out = _no_motion(starts, ends)
    count = ends.shape[0]
    if not count:
        return out
    lengths = ends - starts
    plain = lengths > 0
    # lines with a character no plain block has, or blanks not between two words
    blank = cls == _BLANK
    separator = blank | newline
    odd = np.flatnonzero(cls == _OTHER)
    doubled = np.flatnonzero(blank[1:] & separator[:-1]) + 1  # after a blank or line start
    trailing = np.flatnonzero(blank[:-1] & newline[1:])
    for positions in (odd, doubled, trailing):
        plain[_line_of(starts, positions)] = False
    plain &= ~blank[np.minimum(starts, n - 1)] & ~blank[np.maximum(ends - 1, 0)]
    # tokens: runs of characters between blanks and line breaks
    inside = ~separator
    first = inside.copy()
    first[1:] &= separator[:-1]
    last = inside.copy()
    last[:-1] &= separator[1:]
    tokens = np.flatnonzero(first)
    if not tokens.size:
        return out
    token_len = np.flatnonzero(last) + 1 - tokens
    line = _line_of(starts, tokens)

    owner_of = np.cumsum(first, dtype=np.int32) - 1  # token of each character inside one

    def per_token(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """How many of the characters at ``positions`` each token has, and their tokens."""
        owner = owner_of[positions]
        return np.bincount(owner, minlength=tokens.shape[0]), owner

    head_letter = cls[tokens] == _LETTER
    letter = cls == _LETTER
    inner_letters, _ = per_token(np.flatnonzero(letter[1:] & inside[:-1]) + 1)
    letters = head_letter + inner_letters
    dots, _ = per_token(np.flatnonzero(cls == _POINT_CLASS))
    sign_at = np.flatnonzero(cls == _SIGN)
    signs, sign_owner = per_token(sign_at)
    digits = token_len - letters - dots - signs  # in lines of plain characters
    # a sign goes first in the number: after the letter of a word, at the start of a bare one
    misplaced = sign_at != tokens[sign_owner] + head_letter[sign_owner]
    sign_ok = np.ones(tokens.shape[0], dtype=bool)
    sign_ok[sign_owner[misplaced]] = False
    number_ok = (digits >= 1) & (dots <= 1) & (signs <= 1) & sign_ok
    word = head_letter & (letters == 1) & (token_len >= 2) & number_ok
    bare = ~head_letter & (letters == 0) & number_ok  # a number without a letter
    rank, has_number = _token_ranks(grammar, b, tokens, token_len, word, bare, dots, signs)
    _check_lines(grammar, plain, line, rank)
    # the numbers of the plain lines, in token order, read at once
    if not plain.any():
        return out
    out.plain[:] = plain
    values = np.fromstring(_numbers_text(raw, out, b""), sep=" ")
    read = np.flatnonzero(has_number & plain[line])
    if values.shape[0] != read.shape[0]:  # cannot happen for checked tokens; be safe
        raise _Unread
    return _store_values(grammar, out, line, rank, read, values)


def _fast_lines(
    raw: bytes, grammar: MotionGrammar, starts: np.ndarray, ends: np.ndarray
) -> MotionLines | None:
    """:func:`motion_lines` of one piece of text (ASCII bytes) with its lines, faster.

    Characters are located one by one only where a word starts and where there is a letter,
    point, sign or line break; the numbers are read as integers, their points taken out, and
    divided by powers of ten (exact: the same ``float``).

    Returns
    -------
    MotionLines or None
        None when the piece is beyond this path (2**15 letters, points, signs and line breaks
        from a word to the next, a number of more than 15 digits; a grammar whose keywords
        are not letters only is the caller's to avoid).
    """
    b = np.frombuffer(raw, dtype=np.uint8)
    cls = np.frombuffer(raw.translate(_CLASS_TABLE), dtype=np.uint8)
    n = b.shape[0]
    out = _no_motion(starts, ends)
    plain = ends > starts
    # lines with a character no plain block has, or blanks not between two words
    separator = cls >= _NEWLINE
    blank = cls == _BLANK
    odd = cls == _OTHER
    if odd.any():
        plain[_line_of(starts, np.flatnonzero(odd))] = False
    doubled = blank[1:] & separator[:-1]  # after a blank or line start
    if doubled.any():
        plain[_line_of(starts, np.flatnonzero(doubled) + 1)] = False
    trailing = blank[:-1] & (cls[1:] == _NEWLINE)
    if trailing.any():
        plain[_line_of(starts, np.flatnonzero(trailing))] = False
    if blank[0]:
        plain[0] = False
    if blank[-1]:
        plain[-1] = False
    # tokens, and the characters located: token starts, letters, points, signs, line breaks
    first = ~separator
    first[1:] &= separator[:-1]
    last = ~separator
    last[:-1] &= separator[1:]
    located = (cls - np.uint8(_LETTER)) <= np.uint8(_NEWLINE - _LETTER)
    located |= first
    at = np.flatnonzero(located)
    kind = cls[at]
    is_head = first[at]
    head_at = np.flatnonzero(is_head)  # index into ``at`` of each token start
    tokens = at[head_at]
    if not tokens.size:
        return out
    if at.shape[0] >= 1 << (_FIELD_BITS - 1) and (
        max(int(np.diff(head_at).max(initial=0)), at.shape[0] - int(head_at[-1]))
        >= 1 << (_FIELD_BITS - 1)
    ):
        return None  # a count of a token could overflow its field
    token_len = np.flatnonzero(last) + 1 - tokens
    # counts of each token and the line breaks after it, from its start to the next token's
    head_kind = kind[head_at]
    counted = kind > _LETTER  # points, signs, line breaks
    counted |= (kind == _LETTER) & ~is_head  # letters after the first
    weight = kind.astype(np.int64)
    weight -= _LETTER
    np.maximum(weight, 0, out=weight)
    weight *= _FIELD_BITS
    weight = np.left_shift(counted.astype(np.int64), weight)
    counts = np.add.reduceat(weight, head_at)
    mask = (1 << _FIELD_BITS) - 1
    inner_letters = counts & mask
    dots = (counts >> _FIELD_BITS) & mask
    signs = (counts >> 2 * _FIELD_BITS) & mask
    breaks = counts >> 3 * _FIELD_BITS
    line = np.empty(tokens.shape[0], dtype=np.int64)
    line[0] = head_at[0]  # the characters located before the first token are line breaks
    np.cumsum(breaks[:-1], out=line[1:])
    line[1:] += head_at[0]
    head_letter = head_kind == _LETTER
    letters = head_letter + inner_letters
    digits = token_len - letters - dots - signs  # in lines of plain characters
    # a sign goes first in the number: after the letter of a word, at the start of a bare one
    sign_first = cls[np.minimum(tokens + head_letter, n - 1)] == _SIGN
    number_ok = (digits >= 1) & (dots <= 1) & ((signs == 0) | ((signs == 1) & sign_first))
    word = head_letter & (letters == 1) & (token_len >= 2) & number_ok
    bare = ~head_letter & (letters == 0) & number_ok  # a number without a letter
    rank, has_number = _token_ranks(grammar, b, tokens, token_len, word, bare, dots, signs)
    _check_lines(grammar, plain, line, rank)
    if not plain.any():
        return out
    # the numbers of the plain lines, in token order: integers, scaled by their decimals
    read = np.flatnonzero(has_number & plain[line])
    if int(digits.max()) > _MAX_DIGITS and int(digits[read].max(initial=0)) > _MAX_DIGITS:
        return None
    out.plain[:] = plain
    integers = np.fromstring(_numbers_text(raw, out, b"."), dtype=np.int64, sep=" ")
    if integers.shape[0] != read.shape[0]:  # cannot happen for checked tokens; be safe
        return None
    # the point of a number is the last character located in its token, followed by the line
    # breaks after it
    following = np.empty_like(head_at)
    following[:-1] = head_at[1:]
    following[-1] = at.shape[0]
    point = at[following - 1 - breaks]
    decimals = np.where(dots == 1, tokens + token_len - 1 - point, 0)[read]
    values = integers / _POWERS_OF_TEN[decimals]
    zero = read[integers == 0]
    values[integers == 0] = np.where(b[tokens[zero] + head_letter[zero]] == _MINUS_BYTE, -0.0, 0.0)
    return _store_values(grammar, out, line, rank, read, values)
