"""The encoding of a CL file: UTF-8 (ASCII), with or without a byte-order mark, or UTF-16/32
with one.

CAM systems write ASCII; Windows tools sometimes put a UTF-8 byte-order mark before it, or save
the file as UTF-16 with a mark. Read without care, the mark becomes part of the first record
(``\\ufeffUNITS/INCHES`` is an unknown record, and inch values are then read as mm) and
UTF-16 text becomes records with a NUL between every two characters. So the mark is decoded,
and a NUL byte, which no CL text holds, is an error that names the encoding as the problem.
"""

from __future__ import annotations

import codecs

from urdfpost.errors import CLDataError

#: Byte-order marks and the codec each one selects (UTF-32 before UTF-16: FF FE 00 00 starts
#: with FF FE).
_MARKS = (
    (codecs.BOM_UTF8, "utf-8"),
    (codecs.BOM_UTF32_LE, "utf-32-le"),
    (codecs.BOM_UTF32_BE, "utf-32-be"),
    (codecs.BOM_UTF16_LE, "utf-16-le"),
    (codecs.BOM_UTF16_BE, "utf-16-be"),
)

#: Bytes at the start of a file enough to find any mark.
HEAD_BYTES = 4


def encoding_of(head: bytes) -> tuple[str, int]:
    """The codec of a file that starts with ``head`` and the length of its byte-order mark.

    Parameters
    ----------
    head : bytes
        The file's first bytes (at least :data:`HEAD_BYTES` of them when it has that many).

    Returns
    -------
    (str, int)
        The codec name for :func:`str` / :func:`open` and how many bytes to skip: ``("utf-8",
        0)`` for a file without a mark.
    """
    for mark, codec in _MARKS:
        if head.startswith(mark):
            return codec, len(mark)
    return "utf-8", 0


def check_text(text: str, source: str, first_line: int = 1) -> str:
    """``text`` unchanged when it holds no NUL character, else a :class:`CLDataError`.

    Parameters
    ----------
    text : str
        Decoded text that starts at the start of line ``first_line``.
    source : str
        The file, for the message.
    first_line : int
        Number of the text's first line in the file.

    Raises
    ------
    CLDataError
        At the line of the first NUL: the file is UTF-16 or UTF-32 without a byte-order mark,
        or not text at all.
    """
    nul = text.find("\x00")
    if nul < 0:
        return text
    line = (
        first_line
        + text.count("\n", 0, nul)
        + text.count("\r", 0, nul)
        - text.count("\r\n", 0, nul)
    )
    raise CLDataError(
        source,
        line,
        "a NUL byte: expected text in ASCII or UTF-8 (or UTF-16 with a byte-order mark); the "
        "file may be UTF-16 saved without a byte-order mark, or not a text file",
    )
