"""Many motion blocks at once: their text for the writer, their words for the reader.

Lines are built as rows of a byte matrix: each word has a fixed-width slot, unused bytes are
NUL, and the text is the matrix with the NUL bytes taken out. A number's text is computed from
its value scaled to an integer, which gives exactly the text of
:meth:`~urdfpost.dialects.spec.NumberFormat.format`: the integer is the correctly rounded value
(as Python's ``f"{value:.3f}"`` rounds it) everywhere except within a hair of a rounding tie,
where Python's own formatting gives it.

The reader's side (:func:`motion_lines`) splits the lines of a text into words with array
operations, checks which lines are plain motion blocks, and reads all their numbers with one
call of ``np.fromstring`` (which reads a number as ``float`` does).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from urdfpost.dialects.spec import NumberFormat

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


#: ASCII digits of 0000 to 9999, shape (10000, 4).
_FOUR_DIGITS = ((np.arange(10_000)[:, None] // np.array([1000, 100, 10, 1])) % 10 + _ZERO).astype(
    np.uint8
)


def _digit_columns(magnitude: np.ndarray, width: int) -> np.ndarray:
    """ASCII digits of non-negative integers, most significant first, shape (k, width)."""
    groups = -(-width // 4)
    out = np.empty((magnitude.shape[0], 4 * groups), dtype=np.uint8)
    rest = magnitude
    for g in range(groups - 1, -1, -1):
        rest, low = np.divmod(rest, 10_000)
        out[:, 4 * g : 4 * g + 4] = _FOUR_DIGITS[low]
    return out[:, 4 * groups - width :]


def _digit_count(magnitude: np.ndarray) -> np.ndarray:
    """Decimal digits of non-negative integers (1 for 0), shape (k,)."""
    count = np.ones(magnitude.shape, dtype=np.int64)
    limit = 10
    top = int(magnitude.max()) if magnitude.size else 0
    while limit <= top:
        count += magnitude >= limit
        limit *= 10
    return count


def integer_slots(numbers: np.ndarray) -> np.ndarray:
    """Text of non-negative integers, right-aligned in NUL-padded slots, shape (k, width)."""
    count = _digit_count(numbers)
    width = int(count.max()) if numbers.size else 1
    slots = _digit_columns(numbers, width)
    slots[np.arange(width)[None, :] < (width - count)[:, None]] = 0
    return slots


def number_slots(scaled: np.ndarray, negative: np.ndarray, fmt: NumberFormat) -> np.ndarray:
    """Text of fixed-point numbers as ``fmt`` writes them, in NUL-padded slots.

    Parameters
    ----------
    scaled : ndarray, shape (k,), int64
        The value times ``10**fmt.decimals``, rounded (see :func:`scaled_integers`).
    negative : ndarray, shape (k,), bool
        Whether the value is below zero (a zero text never gets a minus sign).
    fmt : NumberFormat

    Returns
    -------
    ndarray, shape (k, width), uint8
        Sign, integer digits, point and decimals; NUL where the text has nothing.
    """
    d = fmt.decimals
    magnitude = np.abs(scaled)
    whole, fraction = np.divmod(magnitude, 10**d)
    digits = integer_slots(whole)
    k = scaled.shape[0]
    sign = np.where((scaled != 0) & negative, _MINUS, _PLUS if fmt.plus_sign else 0)
    parts = [sign.astype(np.uint8)[:, None], digits]
    if d == 0:
        if fmt.point:
            parts.append(np.full((k, 1), _POINT, dtype=np.uint8))
        return np.hstack(parts)
    decimals = _digit_columns(fraction, d)
    if fmt.trim:
        # keep the decimals up to the last non-zero one; the point when any is kept
        kept = np.zeros(k, dtype=np.int64)
        for col in range(d):
            kept = np.where(decimals[:, col] != _ZERO, col + 1, kept)
        decimals[np.arange(d)[None, :] >= kept[:, None]] = 0
        point = np.where((kept > 0) | fmt.point, _POINT, 0).astype(np.uint8)
    else:
        point = np.full(k, _POINT, dtype=np.uint8)
    parts += [point[:, None], decimals]
    return np.hstack(parts)


def word_slots(text: str, rows: int) -> np.ndarray:
    """The same ASCII word on every row, shape (rows, len(text))."""
    return np.tile(np.frombuffer(text.encode("ascii"), dtype=np.uint8), (rows, 1))


def text_of_rows(matrix: np.ndarray) -> str:
    """The rows of a NUL-padded byte matrix without the NUL bytes, concatenated."""
    flat = matrix.reshape(-1)
    return flat[flat != 0].tobytes().decode("ascii")


# -- reading ---------------------------------------------------------------------------------

#: Rank of each word in a plain motion block: block number, lead or motion code, the axes in
#: AXIS_ORDER, the rapid word, the feed. A block's words come in increasing rank.
_RANK_NUMBER, _RANK_CODE, _RANK_RAPID, _RANK_FEED = 0, 1, 8, 9
_AXIS_RANKS = {"X": 2, "Y": 3, "Z": 4, "A": 5, "B": 6, "C": 7}


#: Character classes of the bytes of a plain motion block; everything else is _OTHER.
_OTHER, _LETTER, _DIGIT, _POINT_CLASS, _SIGN, _BLANK, _NEWLINE = range(7)
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


def _keyword_at(b: np.ndarray, starts: np.ndarray, lengths: np.ndarray, word: str) -> np.ndarray:
    """Which tokens (start offsets, lengths) of the byte array are exactly ``word``."""
    match = lengths == len(word)
    last = b.shape[0] - 1
    for i, char in enumerate(word.encode("ascii")):
        match &= b[np.minimum(starts + i, last)] == char
    return match


def motion_lines(text: str, grammar: MotionGrammar) -> MotionLines:
    """Find and read the plain motion blocks among the lines of ``text``, all at once.

    Parameters
    ----------
    text : str
        Lines separated by ``\\n`` only.
    grammar : MotionGrammar

    Returns
    -------
    MotionLines
        Numbers are read as ``float`` reads them (bit for bit).
    """
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
    empty = MotionLines(starts, ends, np.zeros(count, bool), axes, code, rapid_word, feed)
    if not count:
        return empty
    lengths = ends - starts
    plain = lengths > 0
    # lines with a character no plain block has, or blanks not between two words
    blank = cls == _BLANK
    separator = blank | newline
    odd = np.flatnonzero(cls == _OTHER)
    doubled = np.flatnonzero(blank[1:] & separator[:-1]) + 1  # after a blank or line start
    trailing = np.flatnonzero(blank[:-1] & newline[1:])
    for positions in (odd, doubled, trailing):
        plain[np.searchsorted(starts, positions, side="right") - 1] = False
    plain &= ~blank[np.minimum(starts, n - 1)] & ~blank[np.maximum(ends - 1, 0)]
    # tokens: runs of characters between blanks and line breaks
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

    owner_of = np.cumsum(first, dtype=np.int32) - 1  # token of each character inside one

    def per_token(positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """How many of the characters at ``positions`` each token has, and their tokens."""
        owner = owner_of[positions]
        return np.bincount(owner, minlength=tokens.shape[0]), owner

    head = b[tokens]
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
    rank = np.full(tokens.shape[0], 99, dtype=np.int64)
    has_number = np.zeros(tokens.shape[0], dtype=bool)
    for address, r in _AXIS_RANKS.items():
        hit = word & (head == ord(address))
        if grammar.require_point:
            hit &= dots == 1
        rank[hit] = r
        has_number |= hit
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
        rank[_keyword_at(b, tokens, token_len, grammar.lead)] = _RANK_CODE
    if grammar.rapid_word:
        rank[_keyword_at(b, tokens, token_len, grammar.rapid_word)] = _RANK_RAPID
    # a line is plain when its tokens are known and in increasing rank, with an axis word
    bad_token = rank == 99
    same_line = line[1:] == line[:-1]
    bad_token[1:] |= same_line & (rank[1:] <= rank[:-1])
    plain &= np.bincount(line, weights=bad_token, minlength=count) == 0
    is_axis = (rank >= 2) & (rank <= 7)
    plain &= np.bincount(line, weights=is_axis, minlength=count) > 0
    if grammar.number_required:
        plain &= np.bincount(line, weights=rank == _RANK_NUMBER, minlength=count) > 0
    if grammar.lead:
        plain &= np.bincount(line, weights=rank == _RANK_CODE, minlength=count) > 0
    # the numbers of the plain lines, in token order, read at once
    if not plain.any():
        return empty
    numbers = raw.translate(_NO_LETTERS)
    if not plain.all():
        kept = np.frombuffer(numbers, dtype=np.uint8).copy()
        kept[~np.repeat(plain, lengths + 1)[:n]] = 32
        numbers = kept.tobytes()
    values = np.fromstring(numbers, sep=" ")
    mine = has_number & plain[line]
    if values.shape[0] != int(mine.sum()):  # cannot happen for checked tokens; be safe
        return empty
    value = np.full(tokens.shape[0], np.nan)
    value[mine] = values
    hit = mine & (rank >= 2) & (rank <= 7)
    axes[line[hit], rank[hit] - 2] = value[hit]
    hit = mine & (rank == _RANK_FEED)
    feed[line[hit]] = value[hit]
    plain[line[hit & ~(value > 0.0)]] = False  # the reader refuses F0
    if grammar.codes:
        hit = mine & (rank == _RANK_CODE)
        known = np.zeros(hit.shape, dtype=bool)
        for key, rapid in grammar.codes.items():
            match = hit & (value == key)
            code[line[match]] = 1 if rapid else 0
            known |= match
        plain[line[hit & ~known]] = False
    if grammar.rapid_word:
        hit = plain[line] & (rank == _RANK_RAPID)
        rapid_word[line[hit]] = True
    return MotionLines(starts, ends, plain, axes, code, rapid_word, feed)
