"""The runs of plain GOTO lines of an APT text and their numbers, found and read by one compiled
byte loop (:func:`goto_runs`): the bulk reader of :func:`urdfpost.readers.apt.scan_piece` for
large files.

The numpy path (:func:`urdfpost.readers.apt._bulk_runs_numpy`) finds the blocks of lines that
start with ``GOTO/`` with a regular expression and reads their numbers with ``np.loadtxt``,
several passes over the text and its copies; compiled with numba, it is one pass over the
text's bytes. Imported by :mod:`urdfpost.readers.apt` when a large file is first read (numba's
import takes a quarter of a second); the machine code is cached on disk beside this module
(``__pycache__``), so only the first call after an install compiles it.

The numbers are those ``float()`` (and ``np.loadtxt``) give, bit for bit: a number is read here
only when it is ``[+-]digits[.digits]`` (or ``[+-].digits``) with at most 18 digits whose
integer ``m`` (the digits without the point) is at most 2**53 and with ``k <= 22`` digits after
the point. Then ``m`` and ``10**k`` are exact doubles and ``m / 10**k`` is one IEEE division,
correctly rounded, which is the correctly rounded value of the decimal as written: what
``float()`` returns. A line with any other number (an exponent, more digits, ``nan``) is an
*odd* line: its place and value count are returned and its numbers are read by the caller with
``np.loadtxt``, as the numpy path reads them. Any other line is no GOTO line of a run: the
scanner reads it record by record.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Exact doubles 10**0 ... 10**22.
_POWERS = np.array([10.0**k for k in range(23)])

_NL = 10
_TAB = 9
_SPACE = 32
_COMMA = 44
_DOLLAR = 36
_DOT = 46
_PLUS = 43
_MINUS = 45
_ZERO = 48
_NINE = 57
_MOST_DIGITS = 18
_LARGEST_EXACT = 1 << 53


@njit(cache=True, nogil=True)
def _line_end(data: np.ndarray, i: int) -> int:
    """Offset of the ``\\n`` that ends the line at ``i``, or ``len(data)``."""
    n = data.shape[0]
    while i < n and data[i] != _NL:
        i += 1
    return i


@njit(cache=True, nogil=True, inline="always")
def _goto_head(data: np.ndarray, i: int) -> int:
    """The offset after ``GOTO/`` at offset ``i`` (blanks allowed before the slash, as CATIA
    writes ``GOTO  /``), or -1 when the line is not a GOTO."""
    n = data.shape[0]
    if not (
        i + 5 <= n
        and data[i] == 71  # G
        and data[i + 1] == 79  # O
        and data[i + 2] == 84  # T
        and data[i + 3] == 79  # O
    ):
        return -1
    j = i + 4
    while j < n and _blank(data[j]):
        j += 1
    return j + 1 if j < n and data[j] == 47 else -1  # /


@njit(cache=True, nogil=True)
def _is_goto(data: np.ndarray, i: int) -> bool:
    """Whether a GOTO line (:func:`_goto_head`) starts at offset ``i``."""
    return _goto_head(data, i) >= 0


@njit(cache=True, nogil=True)
def _blank(c: int) -> bool:
    return c == _SPACE or c == _TAB


@njit(cache=True, nogil=True)
def _is_fedrat(data: np.ndarray, i: int) -> bool:
    """Whether ``FEDRAT/`` is at offset ``i``."""
    return (
        i + 7 <= data.shape[0]
        and data[i] == 70  # F
        and data[i + 1] == 69  # E
        and data[i + 2] == 68  # D
        and data[i + 3] == 82  # R
        and data[i + 4] == 65  # A
        and data[i + 5] == 84  # T
        and data[i + 6] == 47  # /
    )


@njit(cache=True, nogil=True)
def _plain_number(data: np.ndarray, j: int) -> tuple[bool, float, int]:
    """Read the number at ``j`` (after any blanks) as :func:`_plain_line` reads one (which
    does it inline: a call per number costs the loop half its speed): whether it is one this
    loop reads exactly, its value, and the offset after it (where the reading stopped when
    not)."""
    n = data.shape[0]
    while j < n and _blank(data[j]):
        j += 1
    negative = False
    if j < n and (data[j] == _MINUS or data[j] == _PLUS):
        negative = data[j] == _MINUS
        j += 1
    m = 0
    digits = j  # the offset of the first digit, then the number of digits
    while j < n and _ZERO <= data[j] <= _NINE:
        m = m * 10 + (data[j] - _ZERO)
        j += 1
    after = 0  # digits after the point
    if j < n and data[j] == _DOT:
        j += 1
        point = j
        while j < n and _ZERO <= data[j] <= _NINE:
            m = m * 10 + (data[j] - _ZERO)
            j += 1
        after = j - point
        digits = j - digits - 1
    else:
        digits = j - digits
    # (m may have wrapped round when there are too many digits: it is not used then)
    if not digits or digits > _MOST_DIGITS or m > _LARGEST_EXACT or after > 22:
        return False, 0.0, j
    value = float(m)
    if after:
        value = value / _POWERS[after]
    return True, -value if negative else value, j


@njit(cache=True, nogil=True)
def _plain_line(data: np.ndarray, head: int, out: np.ndarray) -> tuple[int, int, int, int]:
    """Read the values of the GOTO line whose values start at ``head`` (after its slash,
    :func:`_goto_head`) into ``out`` when they are 3 or 6 numbers this loop reads exactly.

    Returns
    -------
    values : int
        3 or 6, or 0 when the line is not such a line.
    code_end : int
        Offset after the line's code (where its ``$$`` comment starts, else its end).
    comment : int
        1 when the line has a trailing ``$$`` comment, else 0.
    end : int
        Offset of the ``\\n`` that ends the line, or ``len(data)`` (when ``values`` is 0:
        where the reading stopped, before the line's end).
    """
    n = data.shape[0]
    j = head
    count = 0
    while True:
        while j < n and _blank(data[j]):
            j += 1
        negative = False
        if j < n and (data[j] == _MINUS or data[j] == _PLUS):
            negative = data[j] == _MINUS
            j += 1
        m = 0
        digits = j  # the offset of the first digit, then the number of digits
        while j < n and _ZERO <= data[j] <= _NINE:
            m = m * 10 + (data[j] - _ZERO)
            j += 1
        after = 0  # digits after the point
        if j < n and data[j] == _DOT:
            j += 1
            point = j
            while j < n and _ZERO <= data[j] <= _NINE:
                m = m * 10 + (data[j] - _ZERO)
                j += 1
            after = j - point
            digits = j - digits - 1
        else:
            digits = j - digits
        # (m may have wrapped round when there are too many digits: it is not used then)
        if not digits or digits > _MOST_DIGITS or m > _LARGEST_EXACT or after > 22 or count == 6:
            return 0, j, 0, j
        value = float(m)
        if after:
            value = value / _POWERS[after]
        out[count] = -value if negative else value
        count += 1
        while j < n and _blank(data[j]):
            j += 1
        if j < n and data[j] == _COMMA:
            j += 1
            continue
        if count != 3 and count != 6:
            return 0, j, 0, j
        if j == n or data[j] == _NL:
            return count, j, 0, j
        if j + 1 < n and data[j] == _DOLLAR and data[j + 1] == _DOLLAR:
            return count, j, 1, _line_end(data, j + 2)
        return 0, j, 0, j


#: The feed keywords a feed line of a run may have, by their code in the feeds returned
#: (:func:`goto_runs`; 0: none): those of ``urdfpost.readers.apt.FEED_KEYWORDS``.
_FEED_WORDS = np.array([[77, 77, 80, 77], [73, 80, 77, 0], [77, 77, 80, 82], [73, 80, 82, 0]])
_FEED_WORD_LENGTHS = np.array([4, 3, 4, 3])  # MMPM, IPM, MMPR, IPR


@njit(cache=True, nogil=True)
def _word(data: np.ndarray, j: int) -> int:
    """Offset after the letters (A-Z, a-z) at ``j``."""
    n = data.shape[0]
    while j < n and (65 <= data[j] <= 90 or 97 <= data[j] <= 122):
        j += 1
    return j


@njit(cache=True, nogil=True)
def _feed_word(data: np.ndarray, start: int, end: int) -> int:
    """The code of the letters ``data[start:end]`` among :data:`_FEED_WORDS` (any case), from
    1; 0 when they are none of them."""
    for code in range(_FEED_WORDS.shape[0]):
        if end - start != _FEED_WORD_LENGTHS[code]:
            continue
        same = True
        for k in range(end - start):
            if data[start + k] & 0xDF != _FEED_WORDS[code, k]:  # (the letters' upper case)
                same = False
        if same:
            return code + 1
    return 0


@njit(cache=True, nogil=True)
def _plain_feed(data: np.ndarray, i: int) -> tuple[int, float, int, int]:
    """Read the line at ``i`` when it is ``FEDRAT/`` and one number this loop reads exactly,
    with or without one feed keyword (:data:`_FEED_WORDS`, any case) before it or after it,
    comma-separated, blanks around them: ``FEDRAT/MMPM,800.0``, ``FEDRAT/ 800.0000,MMPM``,
    ``FEDRAT/250``; a trailing ``$$`` comment is allowed.

    Returns
    -------
    keyword : int
        The keyword's code (:data:`_FEED_WORDS`, from 1; 0 for none), or -1 when the line is
        not such a line (the other figures are not to be used then).
    value : float
        The number.
    comment : int
        1 when the line has a trailing ``$$`` comment, else 0.
    end : int
        Offset of the ``\\n`` that ends the line, or ``len(data)``.
    """
    n = data.shape[0]
    j = i + 7
    while j < n and _blank(data[j]):
        j += 1
    keyword = 0
    word_end = _word(data, j)
    if word_end > j:  # a keyword first: then a comma
        keyword = _feed_word(data, j, word_end)
        j = word_end
        while j < n and _blank(data[j]):
            j += 1
        if not (keyword and j < n and data[j] == _COMMA):
            return -1, 0.0, 0, j
        j += 1
    ok, value, j = _plain_number(data, j)
    if not ok:
        return -1, 0.0, 0, j
    while j < n and _blank(data[j]):
        j += 1
    if j < n and data[j] == _COMMA and not keyword:  # a keyword after it
        j += 1
        while j < n and _blank(data[j]):
            j += 1
        word_end = _word(data, j)
        keyword = _feed_word(data, j, word_end)
        if not keyword:
            return -1, 0.0, 0, j
        j = word_end
        while j < n and _blank(data[j]):
            j += 1
    if j == n or data[j] == _NL:
        return keyword, value, 0, j
    if j + 1 < n and data[j] == _DOLLAR and data[j + 1] == _DOLLAR:
        return keyword, value, 1, _line_end(data, j + 2)
    return -1, 0.0, 0, j


@njit(cache=True, nogil=True)
def _odd_line(data: np.ndarray, head: int, end: int) -> tuple[int, int, int]:
    """The shape of a GOTO line (its values from ``head``) that :func:`_plain_line` could not
    read: the values
    ``np.loadtxt`` may read (3 or 6: the line's code, before any ``$$``, holds 2 or 5 commas
    and only digits, letters, signs, points and blanks besides), else 0; and, as
    :func:`_plain_line`, where the code ends and whether there is a comment."""
    commas = 0
    j = head
    while j < end:
        c = data[j]
        if c == _COMMA:
            commas += 1
        elif c == _DOLLAR:
            if j + 1 < end and data[j + 1] == _DOLLAR:
                break
            return 0, end, 0
        elif not (
            _blank(c)
            or _ZERO <= c <= _NINE
            or c == _DOT
            or c == _PLUS
            or c == _MINUS
            or 65 <= c <= 90  # A-Z
            or 97 <= c <= 122  # a-z
        ):
            return 0, end, 0
        j += 1
    if commas != 2 and commas != 5:
        return 0, end, 0
    return commas + 1, j, int(j < end)


@njit(cache=True, nogil=True)
def _add_run(
    runs: np.ndarray,
    k: int,
    start: int,
    end: int,
    count: int,
    width: int,
    comments: int,
    first: int,
    first_feed: int,
    feeds: int,
) -> None:
    """Set row ``k`` of ``runs`` to a run's figures (see :func:`goto_runs`), when there is
    room for it."""
    if k < runs.shape[0]:
        runs[k, 0] = start
        runs[k, 1] = end
        runs[k, 2] = count
        runs[k, 3] = width
        runs[k, 4] = comments
        runs[k, 5] = first
        runs[k, 6] = first_feed
        runs[k, 7] = feeds


@njit(cache=True, nogil=True)
def goto_runs(
    data: np.ndarray, least: int, piece: int, run_room: int, odd_room: int, feed_room: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, int, int]:
    """The runs of at least ``least`` GOTO lines of the same value count, with the feed lines
    between them.

    A GOTO line of a run starts with ``GOTO/`` and holds 3 or 6 comma-separated numbers,
    blanks (space, tab) around them, and may end with a ``$$`` comment. Between two GOTO lines
    of a run may be feed lines (:func:`_plain_feed`: ``FEDRAT/`` and one number, with or
    without one keyword), as feed-optimised CL data has before every move; a run starts and
    ends with a GOTO line. A run longer than ``piece`` characters is cut after the first GOTO
    line that makes it that long (when it has ``least`` GOTO lines by then); a last piece of
    fewer lines is added to the piece before.

    The arrays of runs, odd lines and feed lines have the room they are given (no array is
    grown in the loop: numba would count references to it at every line); when they need
    more, the figures returned say how much, and the call is to be made again with that room.

    Parameters
    ----------
    data : ndarray, shape (n,), uint8
        The text, one byte per character (``\\n`` line breaks; a character that is not ASCII
        as any byte that is not, e.g. ``?``).
    least : int
        Fewest GOTO lines in a run (:data:`urdfpost.readers.apt.BULK_MIN_RECORDS`).
    piece : int
        Characters after which a run is cut.
    run_room, odd_room, feed_room : int
        Rows of the arrays of runs, odd lines and feed lines.

    Returns
    -------
    runs : ndarray, shape (r, 8), int64
        Per run: offset of its first line, offset after its last line's ``\\n`` (or ``n``),
        GOTO lines, values per GOTO line (3 or 6), lines with a ``$$`` comment, the offset
        in ``values`` of its first value (the run's values are the next ``GOTO lines * values
        per line`` ones, row after row), the row in ``feeds`` of its first feed line and its
        number of feed lines.
    values : ndarray, shape (v,), float64
        The numbers, as written (those of odd lines NaN, left to be filled).
    odd : ndarray, shape (o, 3), int64
        The lines of the runs whose numbers were not read: offset of the line, offset after
        its code (before its ``$$`` comment, if any) and the offset in ``values`` of its first
        value.
    feeds : ndarray, shape (f, 2), int64
        The feed lines of the runs: how many GOTO lines of its run come before it, and its
        keyword's code (:func:`_plain_feed`).
    feed_values : ndarray, shape (f,), float64
        Their numbers.
    runs_needed, odd_needed, feeds_needed : int
        Rows the arrays of runs, odd lines and feed lines needed: when more than the room
        given, the arrays are incomplete.
    """
    n = data.shape[0]
    lines = 1
    for c in data:
        lines += c == _NL
    most = min(lines, n // 10 + 1)  # a line of a run has at least 10 characters: GOTO/0,0,0
    runs = np.empty((run_room, 8), dtype=np.int64)
    values = np.empty(6 * most, dtype=np.float64)
    odd = np.empty((odd_room, 3), dtype=np.int64)
    feeds = np.empty((feed_room, 2), dtype=np.int64)
    feed_values = np.empty(feed_room, dtype=np.float64)
    row = np.empty(6, dtype=np.float64)
    n_runs = 0
    n_values = 0
    n_odd = 0
    n_feeds = 0
    odd_needed = 0
    feeds_needed = 0
    # the open group of lines: its first line's offset, GOTO lines, value count, comments,
    # the offset of its values, of its odd lines and of its feed lines, and whether it goes
    # on from a run cut off; the feed lines after its last GOTO line (the start of the first,
    # how many, their comments), which are its own only if another GOTO line follows
    start = -1
    count = 0
    width = 0
    comments = 0
    first_value = 0
    first_odd = 0
    first_feed = 0
    goes_on = False
    tail = -1
    tail_feeds = 0
    tail_comments = 0
    i = 0
    while True:
        kind = 0
        comment = 0
        is_odd = False
        code_end = 0
        head = _goto_head(data, i)
        if head >= 0:
            kind, code_end, comment, end = _plain_line(data, head, row)
            if not kind:
                end = _line_end(data, end)
                kind, code_end, comment = _odd_line(data, head, end)
                is_odd = kind != 0
        elif start >= 0 and _is_fedrat(data, i):
            keyword, value, comment, end = _plain_feed(data, i)
            if keyword >= 0:  # a feed line of the open group, if a GOTO line follows
                if n_feeds < feed_room:
                    feeds[n_feeds, 0] = count
                    feeds[n_feeds, 1] = keyword
                    feed_values[n_feeds] = value
                n_feeds += 1
                feeds_needed = max(feeds_needed, n_feeds)
                if tail < 0:
                    tail = i
                tail_feeds += 1
                tail_comments += comment
                if end >= n:
                    break
                i = end + 1
                continue
            end = _line_end(data, end)
        else:
            end = _line_end(data, i)
        if start >= 0 and kind != width:  # the group ends before this line
            stop = i
            if tail >= 0:  # and before its last feed lines
                stop = tail
                n_feeds -= tail_feeds
            group_feeds = n_feeds - first_feed
            if count >= least and count:
                _add_run(
                    runs,
                    n_runs,
                    start,
                    stop,
                    count,
                    width,
                    comments,
                    first_value,
                    first_feed,
                    group_feeds,
                )
                n_runs += 1
            elif goes_on:  # the last lines of a run cut off: added to its piece before
                if n_runs <= run_room:
                    for r in range(first_feed, min(n_feeds, feed_room)):  # counted from its start
                        feeds[r, 0] += runs[n_runs - 1, 2]
                    runs[n_runs - 1, 1] = stop
                    runs[n_runs - 1, 2] += count
                    runs[n_runs - 1, 4] += comments
                    runs[n_runs - 1, 7] += group_feeds
            else:  # too few: read record by record
                n_values = first_value
                n_odd = first_odd
                n_feeds = first_feed
            start = -1
            goes_on = False
            tail, tail_feeds, tail_comments = -1, 0, 0
        if kind:
            if start < 0:
                start, count, width, comments = i, 0, kind, 0
                first_value, first_odd, first_feed = n_values, n_odd, n_feeds
            if is_odd:
                if n_odd < odd_room:
                    odd[n_odd, 0] = i
                    odd[n_odd, 1] = code_end
                    odd[n_odd, 2] = n_values
                n_odd += 1
                odd_needed = max(odd_needed, n_odd)
                for k in range(kind):
                    values[n_values + k] = np.nan
            else:
                for k in range(kind):
                    values[n_values + k] = row[k]
            n_values += kind
            count += 1
            comments += comment + tail_comments
            tail, tail_feeds, tail_comments = -1, 0, 0
            after = end + 1 if end < n else n
            if after - start >= piece and count >= least:  # cut the run here
                _add_run(
                    runs,
                    n_runs,
                    start,
                    after,
                    count,
                    width,
                    comments,
                    first_value,
                    first_feed,
                    n_feeds - first_feed,
                )
                n_runs += 1
                start, count, comments = after, 0, 0
                first_value, first_odd, first_feed = n_values, n_odd, n_feeds
                goes_on = True
        if end >= n:
            break
        i = end + 1
    if start >= 0:  # the group of the last lines
        stop = n
        if tail >= 0:
            stop = tail
            n_feeds -= tail_feeds
        group_feeds = n_feeds - first_feed
        if count >= least and count:
            _add_run(
                runs,
                n_runs,
                start,
                stop,
                count,
                width,
                comments,
                first_value,
                first_feed,
                group_feeds,
            )
            n_runs += 1
        elif goes_on:
            if n_runs <= run_room:
                for r in range(first_feed, min(n_feeds, feed_room)):
                    feeds[r, 0] += runs[n_runs - 1, 2]
                runs[n_runs - 1, 1] = stop
                runs[n_runs - 1, 2] += count
                runs[n_runs - 1, 4] += comments
                runs[n_runs - 1, 7] += group_feeds
        else:
            n_values = first_value
            n_odd = first_odd
            n_feeds = first_feed
    return (
        runs[: min(n_runs, run_room)].copy(),
        values[:n_values],
        odd[: min(n_odd, odd_room)].copy(),
        feeds[: min(n_feeds, feed_room)].copy(),
        feed_values[: min(n_feeds, feed_room)].copy(),
        n_runs,
        odd_needed,
        feeds_needed,
    )


@njit(cache=True, nogil=True)
def plain_goto_lines(data: np.ndarray, feeds: bool) -> tuple[int, bool]:
    """The lines of a text and whether each starts with ``GOTO/`` (or, with ``feeds``,
    ``FEDRAT/``) and none holds ``$``, nor a GOTO line ``P`` or ``p``
    (:func:`urdfpost.readers.apt._only_plain_gotos`, for the streaming pre-scan).

    Parameters
    ----------
    data : ndarray, shape (n,), uint8
        The text, one byte per character (``\\n`` line breaks), starting at a line's start.
    feeds : bool
        Whether FEDRAT lines count as plain (once the file's units are known).

    Returns
    -------
    lines : int
        :func:`urdfpost.readers._stream.line_count` of the text: its ``\\n`` and one more
        unless it ends with one.
    plain : bool
    """
    n = data.shape[0]
    lines = 0
    feed = feeds and _is_fedrat(data, 0)  # whether the line is a FEDRAT line
    plain = feed or _is_goto(data, 0)
    for i in range(n):
        c = data[i]
        if c == _NL:
            lines += 1
            if i + 1 < n:
                feed = feeds and _is_fedrat(data, i + 1)
                if not (feed or _is_goto(data, i + 1)):
                    plain = False
        elif c == _DOLLAR or ((c == 80 or c == 112) and not feed):  # $, P, p
            plain = False
    if n == 0 or data[n - 1] != _NL:
        lines += 1
    return lines, plain
