"""The reading of plain motion blocks of :func:`urdfpost.dialects._bulk.motion_lines`, compiled.

The numpy path classifies every character of the text, locates the words with array
operations and reads their numbers with ``np.fromstring``: some twenty passes over the text.
Compiled with numba it is one loop over the bytes, a line after the other, a word after the
other. Imported by :func:`urdfpost.dialects._bulk.motion_lines` when it is first asked to run
compiled (numba's import takes a third of a second); the machine code is cached on disk beside
this module (``__pycache__``), so only the first call after an install compiles it.

The rules are those of the numpy path (``tests/test_line_kernel.py`` holds the two to the same
arrays, bit for bit): a plain block is words separated by single blanks, each word known to the
grammar, in increasing rank, with an axis word (and the block number and lead when required);
a number is read as the numpy path reads it, its digits as an integer (at most 15 of them)
divided by the power of ten of its decimals, ``-0.0`` for a zero written with a minus sign.
A plain block with a number of more than 15 digits is not read here: the caller reads the text
by the numpy path.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Ranks of the words of a plain block (as in :mod:`urdfpost.dialects._bulk`).
_NUMBER, _CODE, _RAPID, _FEED, _UNKNOWN = 0, 1, 8, 9, 99
#: Most digits of a number read here (below 2**53: exact in a float).
_MAX_DIGITS = 15
#: ``10.0**k``, exact, for k up to the most decimals of a number read here.
_POWERS = np.array([float(10**k) for k in range(_MAX_DIGITS + 1)])

#: What :func:`read_lines` returns in ``status``.
READ, TOO_MANY_DIGITS = 0, 1

_BLANK, _BREAK, _POINT, _PLUS, _MINUS = 32, 10, 46, 43, 45

#: What :func:`read_lines` returns: seven arrays and a status.
_Read = tuple[
    np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int
]


@njit(cache=True, nogil=True, inline="always")
def _axis_rank(head: int) -> int:
    """Rank of the axis word of a letter (X Y Z A B C: 2 to 7), 0 for any other byte."""
    if head == 88:
        return 2
    if head == 89:
        return 3
    if head == 90:
        return 4
    if head == 65:
        return 5
    if head == 66:
        return 6
    if head == 67:
        return 7
    return 0


@njit(cache=True, nogil=True, inline="always")
def _is(b: np.ndarray, start: int, length: int, word: np.ndarray) -> bool:
    """Whether the ``length`` bytes of ``b`` from ``start`` are ``word`` (not empty)."""
    if word.shape[0] == 0 or length != word.shape[0]:
        return False
    for k in range(length):
        if b[start + k] != word[k]:
            return False
    return True


@njit(cache=True, nogil=True)
def read_lines(
    b: np.ndarray,
    breaks: int,
    number_letter: int,
    number_required: bool,
    lead: np.ndarray,
    code_keys: np.ndarray,
    code_rapid: np.ndarray,
    rapid_word: np.ndarray,
    require_point: bool,
) -> _Read:
    """The lines of a text and the words of its plain motion blocks.

    Parameters
    ----------
    b : ndarray, shape (n,), uint8
        The text (ASCII; lines separated by ``\\n`` only), not empty.
    breaks : int
        Line breaks in the text (``bytes.count`` counts them faster than a loop).
    number_letter : int
        Byte of the block number's letter, -1 for block numbers of digits alone.
    number_required : bool
        Whether a plain block has a block number.
    lead : ndarray, shape (k,), uint8
        The lead word (upper case letters; empty for none): a plain block has it.
    code_keys : ndarray, shape (c,), float64
        Values of the motion codes ``G<value>`` (empty: no motion codes).
    code_rapid : ndarray, shape (c,), bool
        Whether each code is the rapid one.
    rapid_word : ndarray, shape (r,), uint8
        The rapid word (upper case letters; empty for none).
    require_point : bool
        Axis values must have a decimal point.

    Returns
    -------
    starts, ends : ndarray, shape (L,), int64
        Offset of each line in the text and of its line break (or the text's end).
    plain : ndarray, shape (L,), bool
    axes : ndarray, shape (L, 6), float64
        X Y Z A B C values as written (NaN without the word).
    code : ndarray, shape (L,), int8
        1 rapid, 0 linear, -1 no code.
    rapid : ndarray, shape (L,), bool
        Whether a plain block has the rapid word.
    feed : ndarray, shape (L,), float64
        Feed word's value as written (NaN without).
    status : int
        :data:`READ`, or :data:`TOO_MANY_DIGITS` (the arrays are then not all written).

    Notes
    -----
    The fields but ``plain`` are those of every line that has only known words in order
    (and what it requires), including one whose feed is not positive or whose motion code
    is not a known one, which is not plain: as the numpy path leaves them.
    """
    n = b.shape[0]
    count = breaks + (b[n - 1] != _BREAK)
    # (every field of every line is written once below: no filling first)
    starts = np.empty(count, dtype=np.int64)
    ends = np.empty(count, dtype=np.int64)
    plain = np.empty(count, dtype=np.bool_)
    axes = np.empty((count, 6))
    code = np.empty(count, dtype=np.int8)
    rapid = np.empty(count, dtype=np.bool_)
    feed = np.empty(count)
    words = np.empty(_FEED + 1)
    has_codes = code_keys.shape[0] > 0
    has_lead = lead.shape[0] > 0
    i = 0
    for row in range(count):
        starts[row] = i
        ok = i < n and b[i] != _BREAK and b[i] != _BLANK
        previous = -1  # rank of the word before
        seen = 0  # bit r: a word of rank r
        long_number = False
        for r in range(_FEED + 1):
            words[r] = np.nan
        while ok:
            # one word: from i to the next blank or line break
            t = i
            head = b[t]
            head_letter = 65 <= head <= 90
            letters = dots = signs = digits = decimals = 0
            sign_ok = True
            negative = False
            integer = 0
            # the common word first, byte after byte without asking what else a byte may be:
            # a letter, a sign, digits, a point, digits (up to 15: more go to the loop below)
            if head_letter:
                letters = 1
                i += 1
            if i < n and (b[i] == _PLUS or b[i] == _MINUS):
                signs = 1
                negative = b[i] == _MINUS
                i += 1
            while i < n and digits < _MAX_DIGITS:
                d = int(b[i]) - 48
                if d < 0 or d > 9:
                    break
                integer = integer * 10 + d
                digits += 1
                i += 1
            if i < n and b[i] == _POINT:
                dots = 1
                i += 1
                while i < n and digits < _MAX_DIGITS:
                    d = int(b[i]) - 48
                    if d < 0 or d > 9:
                        break
                    integer = integer * 10 + d
                    digits += 1
                    decimals += 1
                    i += 1
            # the rest of the word (nothing, in a plain block but for numbers of more than 15
            # digits), character by character
            while i < n:
                c = b[i]
                if 48 <= c <= 57:
                    digits += 1
                    if digits <= _MAX_DIGITS:
                        integer = integer * 10 + (c - 48)
                    if dots:
                        decimals += 1
                elif 65 <= c <= 90:
                    letters += 1
                elif c == _BLANK or c == _BREAK:
                    break
                elif c == _POINT:
                    dots += 1
                elif c == _PLUS or c == _MINUS:
                    signs += 1
                    if i != t + head_letter:
                        sign_ok = False
                    negative = c == _MINUS
                else:
                    ok = False  # a character no plain block has
                    break
                i += 1
            if not ok:
                break
            length = i - t
            number_ok = digits >= 1 and dots <= 1 and signs <= 1 and sign_ok
            word = head_letter and letters == 1 and length >= 2 and number_ok
            bare = not head_letter and letters == 0 and number_ok
            rank = _UNKNOWN
            has_number = False
            if word:
                axis = _axis_rank(head)
                if axis > 0 and (dots == 1 or not require_point):
                    rank = axis
                    has_number = True
                if head == 70:  # F
                    rank = _FEED
                    has_number = True
            whole = dots == 0 and signs == 0
            if number_letter >= 0:
                if word and head == number_letter and whole:
                    rank = _NUMBER
                    has_number = True
            elif bare and whole:
                rank = _NUMBER
                has_number = True
            if has_codes and word and head == 71 and signs == 0:  # G
                rank = _CODE
                has_number = True
            if has_lead and _is(b, t, length, lead):
                rank = _CODE
            if _is(b, t, length, rapid_word):
                rank = _RAPID
            if rank == _UNKNOWN or rank <= previous:
                ok = False
                break
            previous = rank
            seen |= 1 << rank
            if has_number:
                if digits > _MAX_DIGITS:
                    long_number = True
                elif integer == 0:
                    words[rank] = -0.0 if negative else 0.0
                else:
                    value = integer / _POWERS[decimals]
                    words[rank] = -value if negative else value
            # the blank after the word: one, between two words
            if i < n and b[i] == _BLANK:
                i += 1
                if i == n or b[i] == _BLANK or b[i] == _BREAK:
                    ok = False
            else:
                break  # the line's end
        while i < n and b[i] != _BREAK:  # (the rest of a line that is not plain)
            i += 1
        ends[row] = i
        i += 1
        plain[row] = False
        code[row] = -1
        rapid[row] = False
        ok = ok and seen & 0b11111100 != 0  # an axis word
        ok = ok and (not number_required or seen & (1 << _NUMBER) != 0)
        ok = ok and (not has_lead or seen & (1 << _CODE) != 0)
        if not ok:
            for k in range(6):
                axes[row, k] = np.nan
            feed[row] = np.nan
            continue
        if long_number:
            return starts, ends, plain, axes, code, rapid, feed, TOO_MANY_DIGITS
        for k in range(6):
            axes[row, k] = words[2 + k]
        feed[row] = words[_FEED]
        keep = not words[_FEED] <= 0.0  # the reader refuses F0
        if has_codes:
            value = words[_CODE]
            known = False
            for k in range(code_keys.shape[0]):
                if value == code_keys[k]:
                    code[row] = 1 if code_rapid[k] else 0
                    known = True
            keep = keep and (known or np.isnan(value))
        plain[row] = keep
        rapid[row] = keep and seen & (1 << _RAPID) != 0
    return starts, ends, plain, axes, code, rapid, feed, READ
