"""Posting: CL data in, a verified NC program out.

The flow (``docs/architecture.md``): :mod:`~urdfpost.posting.options` resolves the job's settings
once; :func:`~urdfpost.posting.piece.post_piece` posts one piece (the plan, the program, the
collision check); :mod:`~urdfpost.posting.check` reads it back and checks it;
:func:`~urdfpost.posting.whole.post` is one piece, :func:`~urdfpost.posting.stream.post_stream` the
loop over pieces with its verification worker (:mod:`~urdfpost.posting.worker`);
:mod:`~urdfpost.posting.report` holds the figures and the report.

The names below are imported on first use, so that the command line can read
:data:`PIECE_POINTS` without loading the whole post.
"""

from __future__ import annotations

from typing import Any

PIECE_POINTS = 100_000
"""CL points posted, or checked, per piece by default."""

LOOKAHEAD = 50_000
"""CL points a piece's plan sees past its end, at most, by default (a fifth of the piece below
five times this)."""

_LAZY = {
    "PostOptions": "urdfpost.posting.options",
    "Job": "urdfpost.posting.options",
    "resolve": "urdfpost.posting.options",
    "post": "urdfpost.posting.whole",
    "PostResult": "urdfpost.posting.whole",
    "post_piece": "urdfpost.posting.piece",
    "PostedPiece": "urdfpost.posting.piece",
    "post_stream": "urdfpost.posting.stream",
    "StreamResult": "urdfpost.posting.stream",
    "verify_stream": "urdfpost.posting.readback",
    "Report": "urdfpost.posting.report",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'urdfpost.posting' has no attribute {name!r}")


__all__ = ["LOOKAHEAD", "PIECE_POINTS", *_LAZY]
