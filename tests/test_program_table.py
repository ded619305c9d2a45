"""Columnar programs: moves held as tables give the same program as one Move object per move.

``build_program`` used to make one :class:`Move` per row in a Python loop; it now makes the
moves as one :class:`MoveTable` and only the few other blocks one by one. The loop is kept
here (:func:`reference_blocks`, as it was) and run on the same rows, captured from
``build_program``, on several jobs: the blocks must be the same, in the same order, with the
same values bit for bit (compared by ``repr``, which tells every float apart). The rest is the
API of tables and :class:`Blocks`.
"""

from __future__ import annotations

import importlib.util
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import urdfpost.posting.piece as piece_module
from urdfpost import load_machine, read_cl
from urdfpost.dialects import DIALECTS
from urdfpost.posting.body import LIFT, RETURN, TURN, Rows, _event_blocks, program_body
from urdfpost.posting.options import PostOptions, resolve
from urdfpost.posting.piece import post_piece
from urdfpost.posting.report import PieceFigures
from urdfpost.posting.whole import post
from urdfpost.program import (
    REWIND_BEGIN,
    REWIND_END,
    Block,
    Blocks,
    Comment,
    Home,
    Insert,
    Move,
    MoveTable,
    Program,
    Tcp,
    ToolChange,
    rewind_moves,
)
from urdfpost.toolpath import Event, Motion, Toolpath
from urdfpost.verification import program_joints, verify

ROOT = Path(__file__).resolve().parents[1]


# -- the per-move loop build_program had, kept as the reference ------------------------------


def reference_blocks(
    toolpath: Toolpath,
    machine: Any,
    options: PostOptions,
    units: str,
    rows: list[tuple[np.ndarray, np.ndarray, int, int]],
    events: list[Event],
    rewinds: tuple[Any, ...],
) -> list[Block]:
    """The body as the old loop of ``build_program`` made it (one Move per row)."""
    n = len(toolpath)
    axes = machine.axis_names
    rotary = frozenset(a.name for a in machine.rotary)
    lin_cols = list(machine.linear_columns)
    blocks: list[Block] = []
    tcp_state = [False]
    fill = np.where(np.isfinite(toolpath.feed), np.arange(n), n)
    fill = np.minimum.accumulate(fill[::-1])[::-1]
    feeds = np.append(toolpath.feed, np.nan)
    next_feed = feeds[np.append(fill[1:], n)] if n else feeds
    ev = 0
    arrived = -1
    rewind_iter = iter(rewinds)
    scale = 25.4 if units == "inch" else 1.0
    rewind_feed = None if options.rewind_feed is None else options.rewind_feed * scale
    for q, tip, code, kind in rows:
        g = code if code >= 0 else -1 - code
        while ev < len(events) and events[ev].index <= g:
            blocks.extend(_event_blocks(events[ev], tcp_state, options.tcp))
            ev += 1
        if kind == LIFT:
            blocks.append(Comment(next(rewind_iter).comment))
        position = np.where([a in rotary for a in axes], np.degrees(q), q)
        if options.tcp:
            position[lin_cols] = tip
            if not tcp_state[0]:
                blocks.append(Tcp(on=True))
                tcp_state[0] = True
        turning = g == arrived
        rapid = bool(toolpath.motion[g] == Motion.RAPID) and not turning
        f = next_feed[g] if turning else toolpath.feed[g]
        if kind in (LIFT, TURN):
            rapid, f = rewind_feed is None, np.nan if rewind_feed is None else rewind_feed
        feed = float(f) if np.isfinite(f) else None
        blocks.append(
            Move(
                rapid=rapid,
                position=tuple(float(x) for x in position),
                feed=None if rapid else feed,
                cl_line=int(toolpath.line[g]) if code >= 0 else None,
            )
        )
        if kind == RETURN:
            blocks.append(Comment(REWIND_END))
        if code >= 0:
            arrived = g
    for e in events[ev:]:
        blocks.extend(_event_blocks(e, tcp_state, options.tcp))
    if tcp_state[0]:
        blocks.append(Tcp(on=False))
    return blocks


def build_both(
    monkeypatch: pytest.MonkeyPatch, toolpath: Toolpath, machine: Any, options: PostOptions
) -> tuple[Program, list[Block], PieceFigures]:
    """``build_program``'s program, and the reference body made from the same rows."""
    seen: dict[str, Any] = {}
    real = piece_module.program_body

    def capture(tp, m, tcp, rows, events, comments, rewind_feed, **piece):
        seen.update(toolpath=tp, rows=rows, events=list(events))
        # the old loop knew no transitions (start, approach, end: tested on their own) and no
        # path smoothing (tests/test_smoothing_rollover.py); the body without them is what it
        # is compared with
        plain = {**piece, "transitions": None, "work_offset": None, "smoothing": None}
        seen["plain"] = real(tp, m, tcp, rows, events, comments, rewind_feed, **plain)
        return real(tp, m, tcp, rows, events, comments, rewind_feed, **piece)

    monkeypatch.setattr(piece_module, "program_body", capture)
    units = options.units or toolpath.units
    posted = post_piece(toolpath, resolve(options, machine, toolpath.units))
    program = replace(posted.program, blocks=Blocks(seen["plain"]))
    figures = posted.figures
    r = seen["rows"]
    rows = [
        (
            r.q[k],
            r.tip[k],
            int(r.point[k]) if r.reaches[k] else -1 - int(r.point[k]),
            r.kind[k],
        )
        for k in range(len(r))
    ]
    reference = reference_blocks(
        seen["toolpath"],
        machine,
        options,
        units,
        rows,
        seen["events"],
        figures.rewinds,
    )
    return program, reference, figures


def spiral(turns: float = 3.0, n: int = 400, tilt_deg: float = 30.0) -> Toolpath:
    """The tool axis turns about Z at a constant tilt (C runs out of travel on gantry-ca)."""
    az = np.radians(np.linspace(0.0, 360.0 * turns, n))
    t = np.radians(tilt_deg)
    axis = np.stack([np.sin(t) * np.cos(az), np.sin(t) * np.sin(az), np.full(n, np.cos(t))], 1)
    tip = np.stack([40 * np.cos(az), 40 * np.sin(az), np.linspace(0, -6, n)], axis=1)
    motion = np.full(n, Motion.FEED, dtype=np.int8)
    motion[0] = Motion.RAPID
    return Toolpath(
        tip=tip,
        axis=axis,
        feed=np.full(n, 1000.0),
        motion=motion,
        line=np.arange(10, 10 + n),
        events=(
            Event(index=0, kind="tool", line=8, data={"number": 1}),
            Event(index=0, kind="cutter", line=9, data={"diameter": 10.0, "corner_radius": 0}),
            Event(index=0, kind="spindle", line=9, data={"rpm": 10000.0, "direction": "cw"}),
        ),
        source="job.apt",
    )


def hemisphere(tmp_path_factory: pytest.TempPathFactory, points: int) -> Toolpath:
    """The benchmark's hemisphere raster (bench/make_large_cl.py) with ``points`` points."""
    spec = importlib.util.spec_from_file_location("make_large_cl", ROOT / "bench/make_large_cl.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    path = tmp_path_factory.mktemp("hemisphere") / f"hemisphere_{points}.apt"
    return read_cl(module.write_hemisphere(points, path))


def with_events(toolpath: Toolpath) -> Toolpath:
    """The toolpath with events in the middle and at the end: a tool change and a home return
    (TCP goes off and back on), an insert, a stop, an unknown record, events past the end."""
    n = len(toolpath)
    extra = (
        Event(index=n // 3, kind="tool", line=1, data={"number": 2, "diameter": 6.0}),
        Event(index=n // 3, kind="spindle", line=2, data={"rpm": 9000.0, "direction": "cw"}),
        Event(index=n // 2, kind="home", line=3),
        Event(index=n // 2, kind="insert", line=4, data={"text": "M50"}),
        Event(index=n // 2 + 1, kind="stop", line=5, data={"optional": True}),
        Event(index=n - 1, kind="unknown", line=6, data={"text": "THING/1"}),
        Event(index=n, kind="coolant", line=7, data={"mode": "off"}),
        Event(index=n + 5, kind="comment", line=8, data={"text": "after"}),
    )
    return replace(toolpath, events=toolpath.events + extra)


JOBS = {
    "dome": lambda f: read_cl(ROOT / "examples" / "dome.apt"),
    "dome_events": lambda f: with_events(read_cl(ROOT / "examples" / "dome.apt")),
    "spiral": lambda f: spiral(),
    "spiral_events": lambda f: with_events(spiral()),
    "hemisphere": lambda f: hemisphere(f, 5000),
}

CASES = [
    ("dome", "dmu50", {}),
    ("dome", "dmu50", {"units": "inch"}),
    ("dome", "dmu50", {"strategy": "none"}),
    ("dome_events", "dmu50", {}),
    ("dome_events", "dmu50", {"units": "inch", "strategy": "none"}),
    ("spiral", "gantry-ca", {"strategy": "recursive"}),
    ("spiral", "gantry-ca", {"retract": 20.0, "rewind_feed": 3000.0}),
    ("spiral", "gantry-ca", {"units": "inch", "retract": 1.0, "rewind_feed": 100.0}),
    ("spiral_events", "gantry-ca", {"strategy": "recursive"}),
    ("hemisphere", "dmu50", {}),
    ("hemisphere", "dmu50", {"strategy": "none"}),
]


@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "mc"])
@pytest.mark.parametrize(("job", "machine_name", "extra"), CASES)
def test_build_program_equals_the_per_move_loop(
    job, machine_name, extra, tcp, monkeypatch, tmp_path_factory
) -> None:
    toolpath = JOBS[job](tmp_path_factory)
    machine = load_machine(machine_name)
    options = PostOptions(tcp=tcp, **extra)
    program, reference, figures = build_both(monkeypatch, toolpath, machine, options)
    assert len(program.blocks) == len(reference)
    assert repr(program.blocks) == repr(tuple(reference))  # bit for bit, -0.0 and NaN apart
    assert program.blocks == tuple(reference)
    assert [type(b) for b in program.blocks] == [type(b) for b in reference]
    assert program.moves() == [b for b in reference if isinstance(b, Move)]
    # runs of moves are tables: there are no more parts than non-motion blocks, twice
    others = sum(not isinstance(b, Move) for b in reference)
    assert not any(isinstance(p, Move) for p in program.parts)
    assert len(program.parts) <= 2 * others + 1
    # the table arrays are the moves
    table = program.move_table()
    moves = program.moves()
    np.testing.assert_array_equal(table.position, [m.position for m in moves])
    np.testing.assert_array_equal(table.rapid, [m.rapid for m in moves])
    reference_program = replace(program, blocks=tuple(reference))
    np.testing.assert_array_equal(rewind_moves(program), rewind_moves(reference_program))
    if job.startswith("spiral") and "strategy" not in extra:
        assert rewind_moves(program).sum() == 3 * len(figures.rewinds) > 0


def test_the_cases_cover_turns_rewinds_events_and_inserted_rows(monkeypatch) -> None:
    """The jobs above have rows standing on reached points (pole turns), rewinds, TCP switched
    off and on again by events, and rows inserted by the subdivision."""
    gantry, dmu50 = load_machine("gantry-ca"), load_machine("dmu50")
    for tcp in (True, False):
        options = PostOptions(strategy="recursive", tcp=tcp)
        _, reference, figures = build_both(monkeypatch, with_events(spiral()), gantry, options)
        assert figures.rewinds and any(isinstance(b, Insert) for b in reference)
        if tcp:
            assert sum(isinstance(b, Tcp) and b.on for b in reference) == 3
        else:
            assert figures.inserted_blocks > 0
    _, _, figures = build_both(
        monkeypatch, read_cl(ROOT / "examples" / "dome.apt"), dmu50, PostOptions()
    )
    assert figures.pole_turns > 0


def test_no_rows() -> None:
    """A toolpath without motion: the events' blocks only (build_program's body, directly)."""
    tp = spiral(n=2)
    none = {name: getattr(tp, name)[:0] for name in ("tip", "axis", "feed", "motion", "line")}
    tp = replace(tp, **none, events=(Event(0, "comment", 1, {"text": "nothing"}),))
    machine = load_machine("dmu50")
    for tcp in (True, False):
        rows = Rows.empty(len(machine.axis_names))
        body = program_body(tp, machine, tcp, rows, list(tp.events), [], None)
        options = PostOptions(tcp=tcp)
        assert body == reference_blocks(tp, machine, options, "mm", [], list(tp.events), [])
        assert body == [Comment("nothing")]


# -- tables and blocks ------------------------------------------------------------------------


def _table(k: int = 4, width: int = 2) -> MoveTable:
    position = np.arange(k * width, dtype=float).reshape(k, width)
    position[1, 0] = -0.0
    feed = np.full(k, 500.0)
    feed[0] = np.nan
    return MoveTable(position, np.arange(k) == 0, feed, np.where(np.arange(k) % 2, 7, -1))


def test_table_moves_and_blocks_sequence() -> None:
    table = _table()
    moves = table.moves()
    assert moves[0] == Move(True, (0.0, 1.0), None, None)
    assert moves[1] == Move(False, (-0.0, 3.0), 500.0, 7)
    assert repr(moves[1].position[0]) == "-0.0"
    assert all(type(x) is float for m in moves for x in m.position)
    assert type(moves[1].cl_line) is int and type(moves[0].rapid) is bool
    program = Program("P", ("X", "Y"), frozenset(), "mm", False, (ToolChange(1), table, Home()))
    blocks = program.blocks
    assert isinstance(blocks, Blocks) and len(blocks) == 6
    assert blocks[0] == ToolChange(1) and blocks[-1] == Home() and blocks[2] == moves[1]
    assert blocks[-2] == moves[-1] and blocks[1:3] == tuple(moves[:2])
    assert Home() in blocks and moves[3] in blocks
    with pytest.raises(IndexError):
        blocks[6]
    plain = Program("P", ("X", "Y"), frozenset(), "mm", False, (ToolChange(1), *moves, Home()))
    assert plain == program and hash(plain) == hash(program)
    assert plain.blocks == (ToolChange(1), *moves, Home()) == program.blocks
    assert repr(program) == repr(plain)
    assert program.moves() == plain.moves() == moves
    np.testing.assert_array_equal(plain.move_table().position, table.position)
    np.testing.assert_array_equal(plain.move_table().feed, table.feed)
    np.testing.assert_array_equal(plain.move_table().cl_line, table.cl_line)
    assert program.move_table() is table  # one table: no copy
    assert program != replace(plain, blocks=(ToolChange(1), *moves))
    # tuple arithmetic, as on the tuple of blocks
    assert program.blocks * 2 == plain.blocks * 2 == (ToolChange(1), *moves, Home()) * 2
    assert 2 * program.blocks == program.blocks + program.blocks
    assert (Home(),) + program.blocks + (Home(),) == (Home(), *plain.blocks, Home())  # noqa: RUF005
    assert isinstance(program.blocks + (Home(),), Blocks)  # noqa: RUF005


def test_table_is_read_only_and_checks_shapes() -> None:
    table = _table()
    with pytest.raises(ValueError):
        table.position[0, 0] = 1.0
    with pytest.raises(ValueError, match=r"MoveTable.feed: expected shape \(N,\)"):
        MoveTable(np.zeros((3, 2)), np.zeros(3, bool), np.zeros(2), np.zeros(3, int))
    with pytest.raises(ValueError, match=r"move 1 has 3 positions; expected 2"):
        MoveTable.from_moves([Move(True, (1.0, 2.0)), Move(True, (1.0, 2.0, 3.0))], 2)
    nan = MoveTable(np.array([[math.nan, 1.0]]), np.ones(1, bool), np.zeros(1), -np.ones(1, int))
    assert nan.moves()[0].position[0] is math.nan  # NaN moves compare equal, as read singly


def test_rewind_moves_per_part() -> None:
    table = _table()
    body = (
        table,
        Comment(f"  {REWIND_BEGIN.upper()} CL line 12"),
        table.rows(0, 3),
        Comment(REWIND_END),
        Move(True, (1.0, 2.0)),
        Comment(REWIND_BEGIN),
        Move(True, (1.0, 2.0)),
    )
    program = Program("P", ("X", "Y"), frozenset(), "mm", False, body)
    want = [False] * 4 + [True] * 3 + [False, True]
    assert rewind_moves(program).tolist() == want
    plain = replace(program, blocks=tuple(program.blocks))
    assert rewind_moves(plain).tolist() == want


@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "mc"])
@pytest.mark.parametrize("name", sorted(DIALECTS))
def test_tables_write_read_and_verify_as_move_objects(name: str, tcp: bool) -> None:
    """post(): the program and its read back hold their moves as a few tables; writing,
    reading and verifying them gives what the same programs made of Move objects give."""
    dome, dmu50 = read_cl(ROOT / "examples" / "dome.apt"), load_machine("dmu50")
    result = post(dome, dmu50, PostOptions(controller=name, tcp=tcp))
    dialect = DIALECTS[name]
    back = dialect.read(result.text)
    for program in (result.program, back):
        # single moves are only the post's own: one tool's approach (rotaries, above, the
        # approach point) and the rotaries home at the end
        assert sum(isinstance(p, Move) for p in program.parts) <= 4
        assert len(program.parts) < 100 < len(program.move_table())
        plain = replace(program, blocks=tuple(program.blocks))
        assert all(not isinstance(p, MoveTable) for p in plain.parts)
        assert plain == program
        assert dialect.write(plain) == dialect.write(program)
        assert repr(dialect.read(dialect.write(plain))) == repr(
            dialect.read(dialect.write(program))
        )
        checks = [
            verify(p, dmu50, dome, tool_length=result.program.tool_length) for p in (program, plain)
        ]
        assert checks[0] == checks[1]
        pairs = zip(program_joints(dmu50, program), program_joints(dmu50, plain), strict=True)
        for got, want in pairs:
            np.testing.assert_array_equal(got, want)
    assert len(back.move_table()) == len(result.program.move_table())
