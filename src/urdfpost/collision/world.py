"""The collision world: FCL scene of a machine, its tool and the stock, and its queries.

A :class:`CollisionWorld` is built once per machine, tool and stock, and then asked about many
joint vectors: :meth:`CollisionWorld.check` for configurations, :meth:`CollisionWorld.check_moves`
for the straight joint-space moves between them. Geometry is built once; per configuration only
the transforms of the bodies that move relative to the workpiece are updated.

Bodies, and the side of the kinematic chain each belongs to (derived from the URDF tree, no
machine names):

- every ``<collision>`` element of every link (box, cylinder, sphere, mesh). A link is on the
  **head** side when a moving joint of the chain that carries the tool lies between it and the
  root, on the **table** side when one that carries the workpiece does, and in the **static**
  frame when neither does (bed, column, trunnion housing);
- the tool on the head side (:class:`ToolBody`): the cutting part from the tip, the shank above
  it and the holder, which ends at the gauge point;
- the stock (or part) mesh in the workpiece frame, on the workpiece's side.

Pairs checked: every body against every body of another side, and the stock against bodies of
its own side that move relative to it, except the cutting part against the stock (that is
cutting) and machine shapes that already touch at the home pose. ``docs/collisions.md`` lists the
pairs and the limits.

Everything is placed in the workpiece frame, mm. Joint vectors ``q`` have one column per axis in
``machine.axis_names`` order (mm for linear axes, rad for rotary axes), as everywhere in urdfpost.

Examples
--------
>>> from urdfpost.machine import load_machine
>>> machine = load_machine("dmu50")
>>> world = CollisionWorld.build(machine, ToolBody(diameter=10.0), tool_length=100.0)
>>> bool(world.check(machine.home).hit[0])
False
"""

from __future__ import annotations

import functools
import logging
import math
import os
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from urdfpost._compiled import Kernels
from urdfpost.collision.fcl_shapes import (
    MACHINE,
    STOCK,
    Shape,
    _import_fcl,
    machine_shapes,
    stock_shape,
    tool_shapes,
    twin,
)
from urdfpost.collision.mesh import load_mesh, points_inside
from urdfpost.collision.tool import CUTTER, HOLDER, SHANK, ToolBody
from urdfpost.machine import Machine
from urdfpost.units import M_TO_MM

if TYPE_CHECKING:
    import trimesh

log = logging.getLogger(__name__)

HEAD, TABLE, STATIC = "head", "table", "static"
"""Sides of the kinematic chain a body moves with."""

HOME_CONTACT_MM = 0.01
"""Machine shapes closer than this at the home pose (mm) are taken as touching by design (a slide
on its bed, a cradle in its trunnion) and not checked against each other. 0.01 mm: far below any
modelled clearance, above the rounding of FCL's distance between touching faces."""

JOB_BODIES = (CUTTER, SHANK, HOLDER, STOCK)
"""Kinds of the bodies that come with the job (``clearance_of=JOB_BODIES``)."""

DEFAULT_STEP_MM = 1.0
"""Default largest displacement (mm) of any body point between two samples of a move."""

DEFAULT_STEP_DEG = 1.0
"""Default largest rotary axis change (degrees) between two samples of a move."""

_CHUNK = 2048  # configurations whose transforms are computed at once (memory bound)


@dataclass(frozen=True, eq=False)
class Body:
    """One rigid collision shape.

    Attributes
    ----------
    name : str
        The ``<collision name>`` (``link/name`` if the name is taken, the link name if there
        is none), or ``cutter``, ``shank``, ``holder``, ``stock``.
    kind : str
        ``machine``, ``cutter``, ``shank``, ``holder`` or ``stock``.
    link : str
        URDF link it moves with.
    side : str
        ``head``, ``table`` or ``static``.
    axes : frozenset of str
        Machine axes between the root link and ``link``: bodies with equal sets never move
        relative to each other.
    local : ndarray, shape (4, 4)
        Placement of the shape in the link frame, translation in mm.
    center : ndarray, shape (3,)
        Centre of a sphere enclosing the shape, in the shape's own frame, mm.
    radius : float
        Radius of that sphere, mm.
    hull : ndarray, shape (k, 3)
        Points in the shape's own frame, mm: the shape lies within ``pad`` of their convex hull.
    pad : float
        mm.
    """

    name: str
    kind: str
    link: str
    side: str
    axes: frozenset[str]
    local: np.ndarray
    center: np.ndarray
    radius: float
    hull: np.ndarray
    pad: float


@dataclass(frozen=True, eq=False)
class CollisionResult:
    """Collisions of single configurations.

    Attributes
    ----------
    hit : ndarray, shape (n,), bool
        Whether configuration i collides.
    pairs : list of (str, str) or None
        Body names of the first colliding pair found per configuration (tool and head first),
        None where clear.
    clearance : ndarray, shape (n,), mm, or None
        Smallest distance over the checked pairs, 0 where colliding; None unless asked for.
    nearest : list of (str, str) or None, or None
        The pair at that distance; None unless clearance was asked for.
    """

    hit: np.ndarray
    pairs: list[tuple[str, str] | None]
    clearance: np.ndarray | None = None
    nearest: list[tuple[str, str] | None] | None = None


@dataclass(frozen=True, eq=False)
class MoveCollisionResult:
    """Collisions of the straight joint-space moves between consecutive configurations.

    Attributes
    ----------
    hit : ndarray, shape (n - 1,), bool
        Whether move i (from configuration i to i + 1, both ends included) collides.
    pairs : list of (str, str) or None
        Body names of the first colliding pair along each move, None where clear.
    at : ndarray, shape (n - 1,)
        Fraction of the move (0 = start, 1 = end) of the first colliding sample, NaN where
        clear.
    samples : ndarray, shape (n - 1,), int
        Number of intervals each move was cut into (``samples + 1`` configurations checked,
        fewer when a collision ends the scan).
    """

    hit: np.ndarray
    pairs: list[tuple[str, str] | None]
    at: np.ndarray
    samples: np.ndarray


def _side(machine: Machine, path: Sequence[str]) -> str:
    """Side of a link with these machine axes above it."""
    sides = {machine.axis(a).side for a in path}
    return HEAD if HEAD in sides else TABLE if TABLE in sides else STATIC


def _bodies_of(
    machine: Machine, shapes: list[Shape], paths: Mapping[str, Sequence[str]]
) -> tuple[list[Body], list[Any]]:
    """Bodies in reporting order (tool, head, stock, table, static) and their FCL geometries.

    Machine shapes are named by their ``<collision name>``, by ``link/name`` when the name is
    used twice or by a tool or stock body, and by the link name when they have none.
    """
    rank = {CUTTER: 0, SHANK: 1, HOLDER: 2, HEAD: 3, STOCK: 4, TABLE: 5, STATIC: 6}
    shapes = sorted(
        shapes,
        key=lambda s: rank[s.kind if s.kind != MACHINE else _side(machine, paths[s.link])],
    )
    taken = {s.kind for s in shapes if s.kind != MACHINE}
    counts: dict[str, int] = {}
    for s in shapes:
        if s.kind == MACHINE:
            counts[s.name or s.link] = counts.get(s.name or s.link, 0) + 1
    bodies, seen = [], set()
    for s in shapes:
        name = s.kind
        if s.kind == MACHINE:
            name = s.name or s.link
            if name in taken or counts[name] > 1:
                name = f"{s.link}/{name}"
            base, k = name, 1
            while name in seen:
                k += 1
                name = f"{base}#{k}"
        seen.add(name)
        bodies.append(
            Body(
                name=name,
                kind=s.kind,
                link=s.link,
                side=_side(machine, paths[s.link]),
                axes=frozenset(paths[s.link]),
                local=s.local,
                center=s.center,
                radius=s.radius,
                hull=s.hull,
                pad=s.pad,
            )
        )
    return bodies, [s.geometry for s in shapes]


def _levers(machine: Machine, bodies: list[Body], paths: Mapping[str, Sequence[str]]) -> np.ndarray:
    """Per axis: the largest distance of any body point from a rotary axis, mm (1 if linear).

    Bounded over every configuration within travel, at the neutral pose: for a body moved by
    the axis directly (no machine axis between them), the largest distance of its hull from
    the axis line; otherwise the distance from the axis line to the next axis' pivot, plus the
    distances between the pivots further down (rigid), plus the largest travel of every linear
    axis on the way, plus the largest distance of the hull from the last pivot.

    Returns
    -------
    ndarray, shape (m,)
        In ``machine.axis_names`` order.
    """
    import pinocchio as pin

    model = machine.model
    data = model.createData()  # type: ignore[attr-defined]
    pin.forwardKinematics(model, data, pin.neutral(model))
    pin.updateFramePlacements(model, data)
    pivot, direction = {}, {}
    for a in machine.axes:
        jid = model.getJointId(a.name)  # type: ignore[attr-defined]
        pivot[a.name] = np.asarray(data.oMi[jid].translation) * M_TO_MM
        motion = np.asarray(data.joints[jid].S).reshape(6)  # joint frame, linear part first
        direction[a.name] = data.oMi[jid].rotation @ motion[3:]

    def from_line(name: str, x: np.ndarray) -> np.ndarray:
        d = x - pivot[name]
        return np.linalg.norm(d - np.outer(d @ direction[name], direction[name]), axis=1)

    levers = {a.name: 1.0 for a in machine.axes}
    for b in bodies:
        t = data.oMf[model.getFrameId(b.link, pin.FrameType.BODY)].homogeneous.copy()  # type: ignore[attr-defined]
        t[:3, 3] *= M_TO_MM
        t = t @ b.local
        hull = b.hull @ t[:3, :3].T + t[:3, 3]
        path = paths[b.link]
        for k, name in enumerate(path):
            if not machine.axis(name).rotary:
                continue
            below = path[k + 1 :]
            if not below:
                reach = float(from_line(name, hull).max())
            else:
                p = pivot[below[0]]
                reach = float(from_line(name, p[None, :])[0])
                for nxt in below[1:]:
                    reach += float(np.linalg.norm(pivot[nxt] - p))
                    p = pivot[nxt]
                for nxt in below:
                    a = machine.axis(nxt)
                    if not a.rotary:
                        reach += max(abs(a.lower), abs(a.upper))
                reach += float(np.linalg.norm(hull - p, axis=1).max())
            levers[name] = max(levers[name], reach + b.pad)
    return np.array([levers[a.name] for a in machine.axes])


GAP_MM = 1e-3
"""A pair whose bounding boxes are more than this apart (mm) is taken as clear without asking
FCL: 1 um, far above the rounding of the box arithmetic and of FCL's own contact tests."""

_TREE_LEAF = 8  # triangles per leaf box of the stock's box tree
_TREE_FRONTIER = 64  # nodes per query beyond which a query goes to FCL without further culling

COMPILED_FROM = 20_000
"""Configurations of one query (``check``, or ``check_moves``' ends and samples) from which the
box culling runs compiled (:mod:`urdfpost.collision._kernels`, with numba installed: the
``fast`` extra); once loaded, queries of any size use it. Below, and without numba, the numpy
path runs (the same pairs culled, within ``KERNEL_SLACK_MM``). Loading costs about 0.6 s of
CPU once per process (numba's import, LLVM's start, the cached machine code) and saves about
6 us per configuration: a post calls ``check_moves`` about six times on samples of the same
path, so from about 20,000 samples per call it gains (a 10k-point five-axis path has about
40,000; the README's 300-point dome 10,000 per call, even either way)."""

KERNEL_SLACK_MM = 1e-10
"""The compiled culling's gaps are lowered by this (mm), so that it keeps every pair the numpy
path keeps whatever the two round (sums of a few products of coordinates of at most metres:
about 1e-12 mm); far below ``GAP_MM``."""


def _load_kernels() -> ModuleType:
    from urdfpost.collision import _kernels

    return _kernels


KERNELS = Kernels(
    _load_kernels, "collision culling", start=COMPILED_FROM, logger=log, first_line=True
)
"""The compiled culling (:mod:`urdfpost.collision._kernels`): ``KERNELS.get(n)`` for a query of
``n`` configurations, None for the numpy path (without numba, after it failed here, or below
``COMPILED_FROM`` before it was loaded)."""


def warm_kernels() -> bool:
    """Load the compiled culling now (about 0.6 s of CPU once per process; else the first
    query of ``COMPILED_FROM`` configurations pays it), so that every later query uses it.

    Returns
    -------
    bool
        Whether it is available (numba installed, compiled or loaded from its cache here).
    """
    kernels = KERNELS.load()
    if kernels is None:
        return False
    n, b = 1, 2
    rot, center = np.tile(np.eye(3), (n, b, 1, 1)), np.zeros((n, b, 3))
    half, one = np.ones((b, 3)), np.zeros(1, dtype=np.int64)
    tree = np.zeros((1, 3))
    try:
        kernels.pair_bounds(
            rot, center, half, one, one + 1, np.zeros(n), np.zeros((n, 1), bool), True, 0.0
        )
        stock = (np.eye(3), np.zeros(3), tree, tree, 1, np.zeros(n), _TREE_FRONTIER, 0.0)
        kernels.stock_separations(rot, center, half, one, *stock)
        kernels.cull_stock_pairs(np.ones((n, 1), bool), one, one, rot, center, half, *stock)
    except Exception as e:  # numba could not compile or load them here: numpy
        KERNELS.fail(e)
        return False
    return True


def _rotation(axis: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Rotations about unit ``axis`` (3,) by angles ``theta`` (n,) rad, shape (n, 3, 3)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


@dataclass(frozen=True, eq=False)
class _Chain:
    """The Pinocchio model's joints as arrays, to place frames for many configurations at once.

    Attributes
    ----------
    parents : tuple of int
        Per joint (0 = universe), its parent joint.
    placements : ndarray, shape (j, 4, 4)
        Per joint, its placement in the parent joint's frame at zero motion, m.
    columns : tuple of int
        Per joint, its column in the joint vectors, -1 for a joint that is not a machine axis
        (held at its neutral motion, folded into ``placements``).
    rotary : tuple of bool
    axes : ndarray, shape (j, 3)
        Unit rotation axis or translation direction in the joint's frame.
    frame_joints : ndarray, shape (f,), int
        Per placed frame, its joint.
    frame_placements : ndarray, shape (f, 4, 4)
        Per placed frame, its placement in its joint's frame, m.
    """

    parents: tuple[int, ...]
    placements: np.ndarray
    columns: tuple[int, ...]
    rotary: tuple[bool, ...]
    axes: np.ndarray
    frame_joints: np.ndarray
    frame_placements: np.ndarray

    @classmethod
    def of(cls, machine: Machine, frames: Sequence[int]) -> _Chain | None:
        """The chain of a machine, or None when a joint is neither a pure rotation nor a pure
        translation (then placements are computed by Pinocchio one configuration at a time)."""
        import pinocchio as pin

        model = machine.model
        data = model.createData()  # type: ignore[attr-defined]
        pin.forwardKinematics(model, data, pin.neutral(model))
        column_of = {idx: col for col, (idx, _) in enumerate(machine._pin_index)}
        placements = np.tile(np.eye(4), (model.njoints, 1, 1))  # type: ignore[attr-defined]
        axes = np.zeros((model.njoints, 3))  # type: ignore[attr-defined]
        columns, rotary = [-1], [False]
        for j in range(1, model.njoints):  # type: ignore[attr-defined]
            col = column_of.get(model.joints[j].idx_q, -1)  # type: ignore[attr-defined]
            if col < 0:
                placement = data.liMi[j].homogeneous.copy()
                turn = False
            else:
                placement = model.jointPlacements[j].homogeneous.copy()  # type: ignore[attr-defined]
                motion = np.asarray(data.joints[j].S).reshape(6)  # linear part first
                lin, ang = np.linalg.norm(motion[:3]), np.linalg.norm(motion[3:])
                if abs(lin - 1.0) < 1e-12 and ang < 1e-12:
                    turn, axes[j] = False, motion[:3] / lin
                elif abs(ang - 1.0) < 1e-12 and lin < 1e-12:
                    turn, axes[j] = True, motion[3:] / ang
                else:
                    return None
            placements[j] = placement
            columns.append(col)
            rotary.append(turn)
        frame_placements = np.array(
            [model.frames[f].placement.homogeneous for f in frames]  # type: ignore[attr-defined]
        ).reshape(-1, 4, 4)
        return cls(
            parents=tuple(int(p) for p in model.parents),  # type: ignore[attr-defined]
            placements=placements,
            columns=tuple(columns),
            rotary=tuple(rotary),
            axes=axes,
            frame_joints=np.array(
                [model.frames[f].parentJoint for f in frames],  # type: ignore[attr-defined]
                dtype=int,
            ),
            frame_placements=frame_placements,
        )

    def frames(self, q: np.ndarray) -> np.ndarray:
        """Placements of the frames in the root frame, shape (n, f, 4, 4), m (as Pinocchio).

        Parameters
        ----------
        q : ndarray, shape (n, m)
            Joint vectors, mm / rad.
        """
        n = q.shape[0]
        joint = np.empty((len(self.parents), n, 4, 4))
        joint[0] = np.eye(4)
        for j in range(1, len(self.parents)):
            local = np.broadcast_to(self.placements[j], (n, 4, 4))
            col = self.columns[j]
            if col >= 0:
                motion = np.tile(np.eye(4), (n, 1, 1))
                if self.rotary[j]:
                    motion[:, :3, :3] = _rotation(self.axes[j], q[:, col])
                else:
                    motion[:, :3, 3] = (q[:, col] / M_TO_MM)[:, None] * self.axes[j]
                local = local @ motion
            joint[j] = joint[self.parents[j]] @ local
        return np.swapaxes(joint[self.frame_joints], 0, 1) @ self.frame_placements


def _node_boxes(
    lo: np.ndarray, hi: np.ndarray, center: np.ndarray, rot: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What a separating-axis test of tree nodes (corners ``lo``, ``hi``, (k, 3), mm) against
    oriented boxes (``center`` (k, 3), axes ``rot`` (k, 3, 3)) needs: which nodes hold
    triangles, the centre offsets and the nodes' half sizes along the world axes, and the same
    along the oriented boxes' axes (absolute offsets; projected half sizes), each (k, 3)."""
    valid = np.all(lo <= hi, axis=1)
    lo, hi = np.where(valid[:, None], lo, 0.0), np.where(valid[:, None], hi, 0.0)
    mid, ext = (lo + hi) / 2, (hi - lo) / 2
    d = mid - center
    d_box = np.abs(np.einsum("kij,ki->kj", rot, d))
    ext_box = np.einsum("kij,ki->kj", np.abs(rot), ext)
    return valid, d, ext, d_box, ext_box


@dataclass(frozen=True, eq=False)
class _BoxTree:
    """A complete binary tree of axis-aligned boxes over a mesh's triangles (Morton order).

    Attributes
    ----------
    lo, hi : list of ndarray, shape (2**level, 3)
        Per level from the root, the corners of each node's box, mm (+inf / -inf: empty).
    """

    lo: list[np.ndarray]
    hi: list[np.ndarray]

    @functools.cached_property
    def flat(self) -> tuple[np.ndarray, np.ndarray]:
        """The levels one after the other from the root (level l from row ``2**l - 1``):
        corners (2**levels - 1, 3), mm, for the compiled descents."""
        return np.ascontiguousarray(np.vstack(self.lo)), np.ascontiguousarray(np.vstack(self.hi))

    @classmethod
    def of(cls, triangles: np.ndarray) -> _BoxTree:
        """Tree of the triangles, shape (t, 3, 3), mm, in their own frame."""
        centroid = triangles.mean(axis=1)
        low, span = centroid.min(axis=0), np.ptp(centroid, axis=0).max() or 1.0
        cell = np.minimum(((centroid - low) / span * 1023).astype(np.int64), 1023)
        code = np.zeros(len(cell), dtype=np.int64)
        for bit in range(10):
            for axis in range(3):
                code |= ((cell[:, axis] >> bit) & 1) << (3 * bit + axis)
        order = triangles[np.argsort(code, kind="stable")]
        leaves = max(1, -(-len(order) // _TREE_LEAF))
        size = 1 << (leaves - 1).bit_length()
        lo = np.full((size * _TREE_LEAF, 3), np.inf)
        hi = np.full((size * _TREE_LEAF, 3), -np.inf)
        lo[: len(order)], hi[: len(order)] = order.min(axis=1), order.max(axis=1)
        lo_levels = [lo.reshape(size, _TREE_LEAF, 3).min(axis=1)]
        hi_levels = [hi.reshape(size, _TREE_LEAF, 3).max(axis=1)]
        while len(lo_levels[-1]) > 1:
            lo_levels.append(np.minimum(lo_levels[-1][0::2], lo_levels[-1][1::2]))
            hi_levels.append(np.maximum(hi_levels[-1][0::2], hi_levels[-1][1::2]))
        return cls(lo_levels[::-1], hi_levels[::-1])

    def near(
        self, center: np.ndarray, rot: np.ndarray, half: np.ndarray, gap: float | np.ndarray
    ) -> np.ndarray:
        """Whether each oriented box may come within ``gap`` of a leaf box.

        A separating-axis test on the six face normals of the two boxes, node by node from the
        root; False only where every leaf box is more than ``gap`` away.

        Parameters
        ----------
        center : ndarray, shape (k, 3)
            Box centres in the tree's frame, mm.
        rot : ndarray, shape (k, 3, 3)
            Box axes (columns) in the tree's frame.
        half : ndarray, shape (k, 3)
            Half sizes, mm.
        gap : float or ndarray, shape (k,)
            mm (one per box, or one for all).

        Returns
        -------
        ndarray, shape (k,), bool
        """
        k = len(center)
        out = np.zeros(k, dtype=bool)
        half = half + np.reshape(gap, (-1, 1))
        reach = np.einsum("kij,kj->ki", np.abs(rot), half)  # world-axis half sizes
        qi, ni = np.arange(k), np.zeros(k, dtype=int)
        for level, (lo, hi) in enumerate(zip(self.lo, self.hi, strict=True)):
            valid, d, ext, d_box, ext_box = _node_boxes(lo[ni], hi[ni], center[qi], rot[qi])
            keep = valid & np.all(np.abs(d) <= reach[qi] + ext, axis=1)
            keep &= np.all(d_box <= half[qi] + ext_box, axis=1)
            qi, ni = qi[keep], ni[keep]
            if level == len(self.lo) - 1:
                out[qi] = True
                break
            crowded = np.bincount(qi, minlength=k) > _TREE_FRONTIER
            if crowded.any():
                out |= crowded
                stay = ~crowded[qi]
                qi, ni = qi[stay], ni[stay]
            qi, ni = np.repeat(qi, 2), np.stack([2 * ni, 2 * ni + 1], axis=1).ravel()
        return out

    def separation(
        self, center: np.ndarray, rot: np.ndarray, half: np.ndarray, most: np.ndarray
    ) -> np.ndarray:
        """The smallest gap for which :meth:`near` holds, per oriented box, up to ``most``.

        Each node's gap is the largest, over the six face normals of the two boxes, of their
        separation along it, in the measure :meth:`near` inflates the oriented box by (along a
        world axis, divided by the oriented box's extent per unit of inflation); a node inside
        another is never nearer, so ``near(g)`` holds where the smallest leaf's is at most g.
        One descent answers every gap up to ``most``.

        Parameters
        ----------
        center, rot, half
            As :meth:`near`.
        most : ndarray, shape (k,), mm
            The largest gap asked about per box.

        Returns
        -------
        ndarray, shape (k,), mm
            The gap; +inf where every leaf box is more than ``most`` away, -inf where the
            descent stopped (more than ``_TREE_FRONTIER`` nodes within reach: near for any gap).
        """
        k = len(center)
        out = np.full(k, np.inf)
        spread = np.abs(rot).sum(axis=2)  # (k, 3): world extent per unit of inflation
        base = np.einsum("kij,kj->ki", np.abs(rot), half)
        qi, ni = np.arange(k), np.zeros(k, dtype=int)
        for level, (lo, hi) in enumerate(zip(self.lo, self.hi, strict=True)):
            valid, d, ext, d_box, ext_box = _node_boxes(lo[ni], hi[ni], center[qi], rot[qi])
            world = ((np.abs(d) - base[qi] - ext) / spread[qi]).max(axis=1)
            gap = np.maximum(world, (d_box - half[qi] - ext_box).max(axis=1))
            keep = valid & (gap <= most[qi])
            qi, ni, gap = qi[keep], ni[keep], gap[keep]
            if level == len(self.lo) - 1:
                np.minimum.at(out, qi, gap)
                break
            crowded = np.bincount(qi, minlength=k) > _TREE_FRONTIER
            if crowded.any():
                out[crowded] = -np.inf
                stay = ~crowded[qi]
                qi, ni = qi[stay], ni[stay]
            qi, ni = np.repeat(qi, 2), np.stack([2 * ni, 2 * ni + 1], axis=1).ravel()
        return out


def _within(separation: np.ndarray, gap: np.ndarray | float) -> np.ndarray:
    """Where a :meth:`_BoxTree.separation` lets :meth:`_BoxTree.near` hold at ``gap`` (mm),
    with 1e-9 mm to spare for the rounding between the two forms of the test (a pair kept
    for FCL that the other form would have cleared changes no result)."""
    return separation <= np.asarray(gap) + 1e-9


# -- the world ----------------------------------------------------------------------------


class CollisionWorld:
    """FCL scene of one machine, tool and stock; build it with :meth:`build`.

    The world holds FCL objects whose transforms it sets on every query, so one world serves
    one thread at a time. Geometry is never rebuilt after :meth:`build`.

    Attributes
    ----------
    machine : Machine
    tool_length : float
        Gauge point to tip, mm.
    stock_mesh : trimesh.Trimesh or None
        The stock in the workpiece frame, mm.
    """

    machine: Machine
    tool_length: float
    stock_mesh: trimesh.Trimesh | None

    # set by build() and the _setup_* helpers it calls; FCL and Pinocchio objects are untyped
    _fcl: Any  # the fcl module
    _geometries: list[Any]  # per body: its FCL geometry
    _bodies: tuple[Body, ...]
    _stock: int  # index of the stock body, -1 if none
    _objects: list[Any]  # per body: its fcl.CollisionObject
    _index: dict[int, int]  # id of an FCL geometry -> body index
    _crequest: Any  # fcl.CollisionRequest
    _drequest: Any  # fcl.DistanceRequest
    _box_center: np.ndarray  # (b, 3): per body, centre of its box in its own frame, mm
    _box_half: np.ndarray  # (b, 3): per body, half sizes of that box, mm
    _excluded: set[tuple[int, int]]  # body pairs (i < j) touching at home
    _pairs: np.ndarray  # (p, 2), int: body pairs checked
    _levers: np.ndarray  # (m,): per axis, see levers
    _pin: Any  # the pinocchio module
    _data: Any  # pinocchio.Data
    _neutral: np.ndarray  # (nq,)
    _pin_index: tuple[tuple[int, int], ...]  # per axis: (idx_q, nq)
    _moving: list[int]  # bodies that move relative to the workpiece
    _moving_pos: dict[int, int]  # body index -> position in _moving
    _frames: list[int]  # Pinocchio frame ids: the workpiece, then the moving bodies' links
    _moving_link: np.ndarray  # (k,), int: per moving body, its link among _frames[1:]
    _moving_local: np.ndarray  # (k, 4, 4): per moving body, its placement in its link
    _fixed_transform: dict[int, np.ndarray]  # bodies rigid with the workpiece: placement
    _chain: _Chain | None  # vectorised placements (None: Pinocchio per configuration)
    _stock_tree: _BoxTree | None  # boxes over the stock's triangles, in the stock's frame
    _stock_pairs: np.ndarray  # (s,), int: the pairs (rows of _pairs) with the stock
    _twins: dict[int, Any]  # primitive body -> fcl.CollisionObject of its triangulated twin

    @classmethod
    def build(
        cls,
        machine: Machine,
        tool: ToolBody | None = None,
        tool_length: float | None = None,
        stock: str | os.PathLike[str] | trimesh.Trimesh | None = None,
        *,
        home_contact: float = HOME_CONTACT_MM,
    ) -> CollisionWorld:
        """Build the bodies, the FCL objects and the bounding boxes that cull pairs.

        Parameters
        ----------
        machine : Machine
        tool : ToolBody, optional
            Default ``ToolBody()`` (10 mm flat end mill in a 40 x 60 mm holder).
        tool_length : float, optional
            Gauge point to tip, mm; default the machine's ``tool_length`` setting. 0: no tool
            bodies (the gauge point is programmed).
        stock : path or trimesh.Trimesh, optional
            Stock or part mesh in the workpiece frame, mm (STL, OBJ, ... read by trimesh).
        home_contact : float
            Machine shapes closer than this at the home pose are not checked against each
            other, mm (see ``HOME_CONTACT_MM``).

        Returns
        -------
        CollisionWorld

        Raises
        ------
        GeometryError
            A stock or mesh file that is missing or unreadable, a ``<collision>`` element that
            cannot be read, nonsensical tool sizes.
        """
        fcl = _import_fcl()
        self = cls()
        self.machine = machine
        self._fcl = fcl
        self.tool_length = float(
            machine.settings.tool_length if tool_length is None else tool_length
        )
        if not self.tool_length > 0:
            log.info("tool length 0 (gauge point programmed): no tool bodies are checked")
        self.stock_mesh = None
        if stock is not None:
            mesh = load_mesh(stock) if isinstance(stock, str | os.PathLike) else stock
            if not mesh.is_watertight:
                log.warning(
                    "stock mesh is not closed: only contacts with its surface are found, not "
                    "a body entirely inside it"
                )
            self.stock_mesh = mesh

        shapes = tool_shapes(fcl, tool or ToolBody(), self.tool_length)
        shapes += machine_shapes(fcl, machine)
        if self.stock_mesh is not None:
            shapes.append(stock_shape(fcl, self.stock_mesh))
        paths = machine.link_axes
        bodies, self._geometries = _bodies_of(machine, shapes, paths)
        self._bodies = tuple(bodies)
        self._stock = next((i for i, b in enumerate(bodies) if b.kind == STOCK), -1)
        self._objects = [fcl.CollisionObject(g) for g in self._geometries]
        self._index = {id(g): i for i, g in enumerate(self._geometries)}
        self._crequest = fcl.CollisionRequest(num_max_contacts=1, enable_contact=False)
        self._drequest = fcl.DistanceRequest()
        lo = np.array([b.hull.min(axis=0) - b.pad for b in bodies])
        hi = np.array([b.hull.max(axis=0) + b.pad for b in bodies])
        self._box_center, self._box_half = (lo + hi) / 2, (hi - lo) / 2

        self._setup_kinematics(paths["workpiece"])
        self._excluded = set()
        self._exclude_touching_at_home(home_contact)
        self._pairs = np.array(
            [
                (i, j)
                for i in range(len(bodies))
                for j in range(i + 1, len(bodies))
                if self._rule(bodies[i], bodies[j]) and (i, j) not in self._excluded
            ],
            dtype=int,
        ).reshape(-1, 2)
        self._setup_twins()
        self._stock_tree = None
        self._stock_pairs = np.flatnonzero((self._pairs == self._stock).any(axis=1))
        if self.stock_mesh is not None and len(self._stock_pairs):
            self._stock_tree = _BoxTree.of(np.asarray(self.stock_mesh.triangles, dtype=float))
        self._levers = _levers(machine, bodies, paths)
        log.debug(
            "collision world for %s: %d bodies, %d pairs checked, %d excluded",
            machine.name,
            len(bodies),
            len(self._pairs),
            len(self._excluded),
        )
        return self

    def _setup_kinematics(self, work_path: Sequence[str]) -> None:
        """Frames to place the bodies that move in the workpiece frame; place the others."""
        import pinocchio as pin

        model, bodies = self.machine.model, self._bodies
        self._pin = pin
        self._data = model.createData()  # type: ignore[attr-defined]
        self._neutral = pin.neutral(model)
        self._pin_index = self.machine._pin_index
        work_axes = frozenset(work_path)
        self._moving = [i for i, b in enumerate(bodies) if b.axes != work_axes]
        self._moving_pos = {i: k for k, i in enumerate(self._moving)}
        links = sorted({bodies[i].link for i in self._moving})
        frame = {
            lk: model.getFrameId(lk, pin.FrameType.BODY)  # type: ignore[attr-defined]
            for lk in {b.link for b in bodies} | {"workpiece"}
        }
        self._frames = [frame["workpiece"]] + [frame[lk] for lk in links]
        self._moving_link = np.array([links.index(bodies[i].link) for i in self._moving], int)
        self._moving_local = np.array([bodies[i].local for i in self._moving]).reshape(-1, 4, 4)
        self._chain = _Chain.of(self.machine, self._frames)
        # bodies rigid with the workpiece: placed once (at home; any pose gives the same)
        data = self._data
        pin.forwardKinematics(model, data, self._pin_q(self.machine.home[None, :])[0])
        w_inv = np.linalg.inv(pin.updateFramePlacement(model, data, frame["workpiece"]).homogeneous)
        self._fixed_transform = {}
        for i, b in enumerate(bodies):
            if i not in self._moving_pos:
                t = w_inv @ pin.updateFramePlacement(model, data, frame[b.link]).homogeneous
                t[:3, 3] *= M_TO_MM
                self._fixed_transform[i] = t @ b.local
                self._place(self._objects[i], t @ b.local)

    def _exclude_touching_at_home(self, home_contact: float) -> None:
        """Leave out pairs of machine shapes that touch at the home pose; say which."""
        fcl, bodies = self._fcl, self._bodies
        self._set_moving(self._moving_transforms(self.machine.home[None, :])[0])
        for i in range(len(bodies)):
            for j in range(i + 1, len(bodies)):
                bi, bj = bodies[i], bodies[j]
                if bi.kind != MACHINE or bj.kind != MACHINE or not self._rule(bi, bj):
                    continue
                oi, oj = self._objects[i], self._objects[j]
                touching = fcl.collide(oi, oj, self._crequest, fcl.CollisionResult()) or (
                    fcl.distance(oi, oj, self._drequest) <= home_contact
                )
                if touching:
                    self._excluded.add((i, j))
                    # neighbours across one axis (a slide on its bed) are expected to touch
                    neighbours = len(bi.axes ^ bj.axes) == 1
                    (log.info if neighbours else log.warning)(
                        "%s: %s (%s) and %s (%s) touch at the home pose: not checked against "
                        "each other",
                        self.machine.name,
                        bi.name,
                        bi.link,
                        bj.name,
                        bj.link,
                    )

    def _setup_twins(self) -> None:
        """Triangulated twins of the primitives paired with a mesh, for distances."""
        fcl = self._fcl
        meshes = {i for i, g in enumerate(self._geometries) if isinstance(g, fcl.BVHModel)}
        self._twins = {}
        for pair in self._pairs:
            for a, b in (pair, pair[::-1]):
                a, b = int(a), int(b)
                if b in meshes and a not in meshes and a not in self._twins:
                    copy = twin(fcl, self._geometries[a])
                    if copy is not None:
                        self._twins[a] = fcl.CollisionObject(copy)
                        if a in self._fixed_transform:
                            self._place(self._twins[a], self._fixed_transform[a])

    @staticmethod
    def _rule(a: Body, b: Body) -> bool:
        """Whether bodies a and b are checked against each other (before home exclusions)."""
        if a.axes == b.axes:
            return False  # rigidly connected
        kinds = {a.kind, b.kind}
        if kinds == {CUTTER, STOCK}:
            return False  # that is cutting
        return a.side != b.side or STOCK in kinds

    # -- description ---------------------------------------------------------------------

    @property
    def bodies(self) -> tuple[Body, ...]:
        """Every body, in reporting order (tool, head, stock, table, static)."""
        return self._bodies

    @property
    def excluded(self) -> tuple[tuple[str, str], ...]:
        """Pairs of machine shapes not checked because they touch at the home pose."""
        b = self._bodies
        return tuple((b[i].name, b[j].name) for i, j in sorted(self._excluded))

    @property
    def levers(self) -> dict[str, float]:
        """Per axis: largest distance of a body point from a rotary axis (mm), 1 for linear."""
        return dict(zip(self.machine.axis_names, self._levers.tolist(), strict=True))

    def checked_pairs(self) -> list[tuple[str, str]]:
        """Every pair of bodies checked against each other, by name."""
        b = self._bodies
        return [
            (b[i].name, b[j].name)
            for i in range(len(b))
            for j in range(i + 1, len(b))
            if self._rule(b[i], b[j]) and (i, j) not in self._excluded
        ]

    # -- kinematics ----------------------------------------------------------------------

    def _as_q(self, q: np.ndarray) -> np.ndarray:
        m = len(self.machine.axes)
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != m:
            raise ValueError(
                f"expected joint vectors of shape (n, {m}) ({' '.join(self.machine.axis_names)}),"
                f" got {q.shape}"
            )
        bad = ~np.isfinite(q).all(axis=1)
        if bad.any():
            raise ValueError(f"joint vectors with NaN or inf at rows {np.flatnonzero(bad)[:10]}")
        return q

    def _pin_q(self, q: np.ndarray) -> np.ndarray:
        """Pinocchio configurations, shape (n, nq)."""
        qp = np.tile(self._neutral, (q.shape[0], 1))
        for col, ((idx, nq), a) in enumerate(zip(self._pin_index, self.machine.axes, strict=True)):
            if nq == 2:
                qp[:, idx], qp[:, idx + 1] = np.cos(q[:, col]), np.sin(q[:, col])
            elif a.rotary:
                qp[:, idx] = q[:, col]
            else:
                qp[:, idx] = q[:, col] / M_TO_MM
        return qp

    def _moving_transforms(self, q: np.ndarray, pinocchio: bool = False) -> np.ndarray:
        """Placements of the moving bodies in the workpiece frame, shape (n, k, 4, 4), mm.

        All configurations at once from the joints' arrays (:class:`_Chain`); with
        ``pinocchio`` (or for a joint that is not a plain rotation or translation) by Pinocchio
        one configuration at a time, the reference the tests hold the arrays to.
        """
        if self._chain is not None and not pinocchio:
            out = self._chain.frames(q)
        else:
            pin, model, data = self._pin, self.machine.model, self._data
            qp = self._pin_q(q)
            out = np.empty((q.shape[0], len(self._frames), 4, 4))
            for i in range(q.shape[0]):
                pin.forwardKinematics(model, data, qp[i])
                for k, f in enumerate(self._frames):
                    out[i, k] = pin.updateFramePlacement(model, data, f).homogeneous
        rel = np.linalg.inv(out[:, :1]) @ out[:, 1:]
        rel[:, :, :3, 3] *= M_TO_MM
        return rel[:, self._moving_link] @ self._moving_local

    @staticmethod
    def _place(obj: Any, t: np.ndarray) -> None:
        obj.setRotation(t[:3, :3])
        obj.setTranslation(t[:3, 3])

    def _set_moving(self, transforms: np.ndarray) -> None:
        for k, i in enumerate(self._moving):
            self._place(self._objects[i], transforms[k])

    # -- queries -------------------------------------------------------------------------

    def _boxes(self, transforms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Axes (n, b, 3, 3) and centres (n, b, 3, mm) of every body's box, workpiece frame."""
        n, bodies = transforms.shape[0], self._bodies
        rot = np.empty((n, len(bodies), 3, 3))
        center = np.empty((n, len(bodies), 3))
        for i, t in self._fixed_transform.items():
            rot[:, i] = t[:3, :3]
            center[:, i] = t[:3, :3] @ self._box_center[i] + t[:3, 3]
        for k, i in enumerate(self._moving):
            t = transforms[:, k]
            rot[:, i] = t[:, :3, :3]
            center[:, i] = np.einsum("nij,j->ni", t[:, :3, :3], self._box_center[i]) + t[:, :3, 3]
        return rot, center

    def _lower_bounds(
        self,
        transforms: np.ndarray,
        pairs: np.ndarray,
        need: float | np.ndarray = np.inf,
        boxes: tuple[np.ndarray, np.ndarray] | None = None,
        kernels: ModuleType | None = None,
    ) -> np.ndarray:
        """Lower bounds of the distance of each pair, shape (n, p), mm.

        Each body is enclosed in an oriented box (the bounding box of its hull points in its
        own frame) and that box in an axis-aligned one of the workpiece frame. The bound is
        the gap between the two axis-aligned boxes and, where that is at most ``need`` (mm;
        or one per configuration, shape (n,)), the larger of it and the largest gap between
        the two oriented boxes along any of their six axes (a separating-axis test that
        measures the gap). Callers that ask whether a pair is within ``need`` get the answer
        of the oriented boxes everywhere. ``boxes``: :meth:`_boxes` of ``transforms``, if known.
        ``kernels`` (:data:`KERNELS`): computed by :func:`._kernels.pair_bounds`, every bound
        lowered by ``KERNEL_SLACK_MM`` (so at most the numpy bound wherever that is within
        ``need``).
        """
        rot, center = self._boxes(transforms) if boxes is None else boxes
        if kernels is not None and KERNELS.failed is None:
            n = len(rot)
            try:
                out: np.ndarray = kernels.pair_bounds(
                    rot,
                    center,
                    self._box_half,
                    np.ascontiguousarray(pairs[:, 0], dtype=np.int64),
                    np.ascontiguousarray(pairs[:, 1], dtype=np.int64),
                    np.array(np.broadcast_to(need, (n,)), dtype=float),
                    np.zeros((0, 0), dtype=bool),
                    False,
                    KERNEL_SLACK_MM,
                )
                return out
            except Exception as e:  # numba could not compile or load it here: numpy
                KERNELS.fail(e)
        ia, ib = pairs[:, 0], pairs[:, 1]
        extent = self._extents(rot)
        between = center[:, ib] - center[:, ia]  # (n, p, 3)
        out = (np.abs(between) - extent[:, ia] - extent[:, ib]).max(axis=2)
        np.maximum(out, 0.0, out=out)
        s_k, p_k = np.nonzero(out <= np.reshape(need, (-1, 1)))
        if len(s_k):
            gaps = self._box_gaps(rot, between[s_k, p_k], s_k, ia[p_k], ib[p_k])
            out[s_k, p_k] = np.maximum(gaps, out[s_k, p_k])
        return out

    def _extents(self, rot: np.ndarray) -> np.ndarray:
        """Half sizes (n, b, 3, mm) of the axis-aligned boxes of every body's oriented box
        (axes ``rot``, (n, b, 3, 3))."""
        extent: np.ndarray = (np.abs(rot) @ self._box_half[None, :, :, None])[..., 0]
        return extent

    def _box_gaps(
        self, rot: np.ndarray, between: np.ndarray, s_k: np.ndarray, a: np.ndarray, b: np.ndarray
    ) -> np.ndarray:
        """The largest gap between the oriented boxes of bodies ``a`` and ``b`` along any of
        their six axes, in configurations ``s_k`` (shape (k,) each; ``between``: centre of b
        less centre of a, (k, 3), mm); negative where they overlap along every axis."""
        r_a, r_b = rot[s_k, a], rot[s_k, b]  # (k, 3, 3), columns = box axes
        axes = np.concatenate([r_a, r_b], axis=2)  # (k, 3, 6)
        d = np.abs(between[:, None, :] @ axes)[:, 0]
        half_a = np.abs(np.swapaxes(r_a, 1, 2) @ axes)  # |a_i . u_l|, (k, 3, 6)
        half_b = np.abs(np.swapaxes(r_b, 1, 2) @ axes)
        box_half = self._box_half
        reach = (box_half[a][:, None, :] @ half_a)[:, 0] + (box_half[b][:, None, :] @ half_b)[:, 0]
        gaps: np.ndarray = (d - reach).max(axis=1)
        return gaps

    def _asked_bounds(
        self,
        boxes: tuple[np.ndarray, np.ndarray],
        allowed: np.ndarray,
        need: float,
        kernels: ModuleType | None = None,
    ) -> np.ndarray:
        """Where the pairs ``allowed`` (n, p) may come within ``need`` (mm): the test of
        :meth:`_lower_bounds` ``<= need``, made for those pairs only (False elsewhere)."""
        rot, center = boxes
        if kernels is not None and KERNELS.failed is None:
            pairs = self._pairs
            try:
                bounds = kernels.pair_bounds(
                    rot,
                    center,
                    self._box_half,
                    np.ascontiguousarray(pairs[:, 0], dtype=np.int64),
                    np.ascontiguousarray(pairs[:, 1], dtype=np.int64),
                    np.full(len(rot), float(need)),
                    np.ascontiguousarray(allowed, dtype=bool),
                    True,
                    KERNEL_SLACK_MM,
                )
                return np.asarray(bounds <= need)
            except Exception as e:  # numba could not compile or load it here: numpy
                KERNELS.fail(e)
        s_k, p_k = np.nonzero(allowed)
        ask = np.zeros(allowed.shape, dtype=bool)
        if not len(s_k):
            return ask
        ia, ib = self._pairs[p_k, 0], self._pairs[p_k, 1]
        extent = self._extents(rot)
        between = center[s_k, ib] - center[s_k, ia]  # (k, 3)
        gap = (np.abs(between) - extent[s_k, ia] - extent[s_k, ib]).max(axis=1)
        np.maximum(gap, 0.0, out=gap)
        near = np.flatnonzero(gap <= need)
        if len(near):
            obb = self._box_gaps(rot, between[near], s_k[near], ia[near], ib[near])
            gap[near] = np.maximum(obb, gap[near])
        ask[s_k, p_k] = gap <= need
        return ask

    def _distance(self, i: int, j: int, transforms: np.ndarray) -> float:
        """Distance between bodies i and j placed by ``transforms`` (moving bodies), mm."""
        fcl = self._fcl
        objects = []
        for a, b in ((i, j), (j, i)):
            twin = self._twins.get(a)
            if twin is not None and isinstance(self._geometries[b], fcl.BVHModel):
                if a in self._moving_pos:
                    self._place(twin, transforms[self._moving_pos[a]])
                objects.append(twin)
            else:
                objects.append(self._objects[a])
        return float(fcl.distance(objects[0], objects[1], self._drequest))

    def _nearest(
        self, transforms: np.ndarray, pairs: np.ndarray, bounds: np.ndarray
    ) -> tuple[float, tuple[int, int] | None]:
        """Smallest distance over ``pairs``, visiting them by increasing lower bound."""
        best, arg = math.inf, None
        for p in np.argsort(bounds):
            if bounds[p] >= best:
                break
            i, j = int(pairs[p, 0]), int(pairs[p, 1])
            d = self._distance(i, j, transforms)
            if d < best:
                best, arg = max(d, 0.0), (i, j)
                if best <= 0.0:
                    break
        return best, arg

    def _inside_stock(self, transforms: np.ndarray, clear: np.ndarray) -> np.ndarray:
        """Index of a head-side body entirely inside the (closed) stock, -1 if none.

        Parameters
        ----------
        transforms : ndarray, shape (n, k, 4, 4)
            Moving body placements.
        clear : ndarray, shape (n,), bool
            Configurations to test.

        Returns
        -------
        ndarray, shape (n,), int
            Body index.
        """
        n = transforms.shape[0]
        out = np.full(n, -1)
        mesh = self.stock_mesh
        if mesh is None or not mesh.is_watertight or not clear.any():
            return out
        lo, hi = mesh.bounds
        for k, i in enumerate(self._moving):
            b = self._bodies[i]
            if b.side != HEAD or b.kind == CUTTER:
                continue
            c = transforms[:, k, :3, :3] @ b.center + transforms[:, k, :3, 3]
            within = clear & (out < 0) & np.all((c - b.radius > lo) & (c + b.radius < hi), axis=1)
            if within.any():
                rows = np.flatnonzero(within)
                out[rows[points_inside(mesh, c[rows])]] = i
        return out

    def _first_pairs(
        self,
        q: np.ndarray,
        plain: bool = False,
        allowed: np.ndarray | None = None,
        kernels: ModuleType | None = None,
    ) -> np.ndarray:
        """The first colliding pair of each configuration, shape (n, 2), body indices, -1 clear.

        The pair reported is the first in checking order (:attr:`_pairs`: tool, head, stock,
        table, static) that FCL finds in contact, else a head-side body entirely inside the
        closed stock. FCL is asked only about the pairs that may touch: the pairs whose boxes
        are more than ``GAP_MM`` apart (:meth:`_lower_bounds`), and the stock pairs whose
        partner's box is more than that from every leaf box of the stock's tree, are clear.
        ``plain``: FCL on every pair, placements by Pinocchio (the reference of the tests).
        ``allowed`` (n, p): the pairs that can touch at all (the others are known clear).
        ``kernels`` (:data:`KERNELS`): the culling compiled (a few more pairs within
        ``KERNEL_SLACK_MM`` of a limit may be handed to FCL, none fewer).
        """
        pairs = self._pairs
        out = np.full((q.shape[0], 2), -1)
        for start in range(0, q.shape[0], _CHUNK):
            rows = slice(start, min(start + _CHUNK, q.shape[0]))
            transforms = self._moving_transforms(q[rows], pinocchio=plain)
            first = out[rows]
            if plain:
                ask = np.ones((transforms.shape[0], len(pairs)), dtype=bool)
            else:
                boxes = self._boxes(transforms)
                if allowed is None:
                    bounds = self._lower_bounds(transforms, pairs, GAP_MM, boxes, kernels)
                    ask = bounds <= GAP_MM
                else:  # the bounds of the pairs that can touch at all only
                    ask = self._asked_bounds(boxes, allowed[rows], GAP_MM, kernels)
                self._cull_stock_pairs(transforms, ask, boxes=boxes, kernels=kernels)
            first[:] = self._first_asked(transforms, ask)
        return out

    def _first_asked(self, transforms: np.ndarray, ask: np.ndarray) -> np.ndarray:
        """:meth:`_first_pairs` of placed configurations, FCL asked about the pairs of ``ask``
        (k, p) only, shape (k, 2)."""
        fcl, pairs = self._fcl, self._pairs
        first = np.full((transforms.shape[0], 2), -1)
        placed = np.full(len(self._bodies), -1)
        for r in np.flatnonzero(ask.any(axis=1)):
            for p in np.flatnonzero(ask[r]):
                i, j = int(pairs[p, 0]), int(pairs[p, 1])
                for b in (i, j):
                    if b in self._moving_pos and placed[b] != r:
                        self._place(self._objects[b], transforms[r, self._moving_pos[b]])
                        placed[b] = r
                if fcl.collide(
                    self._objects[i], self._objects[j], self._crequest, fcl.CollisionResult()
                ):
                    first[r] = (i, j)
                    break
        inside = self._inside_stock(transforms, first[:, 0] < 0)
        rows_in = np.flatnonzero(inside >= 0)
        first[rows_in, 0], first[rows_in, 1] = inside[rows_in], self._stock
        return first

    def _cull_stock_pairs(
        self,
        transforms: np.ndarray,
        ask: np.ndarray,
        gap: float | np.ndarray = GAP_MM,
        boxes: tuple[np.ndarray, np.ndarray] | None = None,
        kernels: ModuleType | None = None,
    ) -> None:
        """Clear, in ``ask`` (n, p), the stock pairs whose partner's box keeps ``gap`` (mm; or
        one per configuration, shape (n,)) from every leaf box of the stock's tree (``boxes``:
        :meth:`_boxes` of ``transforms``, if known; ``kernels``: :data:`KERNELS`, the
        descents compiled, within ``KERNEL_SLACK_MM``)."""
        gaps = np.broadcast_to(np.asarray(gap, dtype=float), (len(ask),))
        tree = self._stock_tree
        if tree is None or not ask[:, self._stock_pairs].any():
            return
        boxes = self._boxes(transforms) if boxes is None else boxes
        if kernels is not None and KERNELS.failed is None:
            rot, center = boxes
            lo, hi = tree.flat
            r_inv, t_s = self._stock_frame()
            work = np.ascontiguousarray(ask, dtype=bool)
            try:
                kernels.cull_stock_pairs(
                    work,
                    np.ascontiguousarray(self._stock_pairs, dtype=np.int64),
                    self._stock_partners(),
                    rot,
                    center,
                    self._box_half,
                    r_inv,
                    t_s,
                    lo,
                    hi,
                    len(tree.lo),
                    np.array(gaps, dtype=float),
                    _TREE_FRONTIER,
                    KERNEL_SLACK_MM,
                )
                ask[:] = work
                return
            except Exception as e:  # numba could not compile or load it here: numpy
                KERNELS.fail(e)
        for p in self._stock_pairs:
            rows = np.flatnonzero(ask[:, p])
            if len(rows):
                ask[rows, p] = tree.near(*self._partner_box(boxes, rows, p), gaps[rows])

    def _stock_partners(self) -> np.ndarray:
        """Per stock pair (``_stock_pairs``), the stock's partner body, shape (s,), int64."""
        pairs, s = self._pairs[self._stock_pairs], self._stock
        return np.ascontiguousarray(np.where(pairs[:, 1] == s, pairs[:, 0], pairs[:, 1]), np.int64)

    def _stock_frame(self) -> tuple[np.ndarray, np.ndarray]:
        """The stock's rotation transposed (3, 3) and origin (3,), mm, in the workpiece frame."""
        stock_t = self._fixed_transform[self._stock]
        return np.ascontiguousarray(stock_t[:3, :3].T), np.ascontiguousarray(stock_t[:3, 3])

    def _partner_box(
        self, boxes: tuple[np.ndarray, np.ndarray], rows: np.ndarray | slice, p: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The oriented box of stock pair p's other body in configurations ``rows``, in the
        stock's frame (where its tree is): centres (k, 3) mm, axes (k, 3, 3), half sizes
        (k, 3) mm (``boxes``: :meth:`_boxes`)."""
        rot, center = boxes
        s = self._stock
        stock_t = self._fixed_transform[s]
        r_inv, t_s = stock_t[:3, :3].T, stock_t[:3, 3]
        other = int(self._pairs[p, 0] if self._pairs[p, 1] == s else self._pairs[p, 1])
        c = (center[rows, other] - t_s) @ r_inv.T
        r = r_inv @ rot[rows, other]
        return c, r, np.broadcast_to(self._box_half[other], (len(c), 3))

    def _stock_separations(
        self,
        transforms: np.ndarray,
        most: np.ndarray,
        boxes: tuple[np.ndarray, np.ndarray],
        kernels: ModuleType | None = None,
    ) -> np.ndarray:
        """:meth:`_BoxTree.separation` of the partner of every stock pair from the stock's
        leaf boxes, up to ``most`` (n,) mm, shape (n, s) in the order of ``_stock_pairs``
        (``_cull_stock_pairs`` at gap g clears where it is more than g). ``kernels``
        (:data:`KERNELS`): by :func:`._kernels.stock_separations`, lowered by
        ``KERNEL_SLACK_MM`` (at most the numpy figure; -inf wherever that is)."""
        tree = self._stock_tree
        assert tree is not None  # asked with a stock only
        if kernels is not None and KERNELS.failed is None:
            rot, center = boxes
            lo, hi = tree.flat
            r_inv, t_s = self._stock_frame()
            try:
                sep: np.ndarray = kernels.stock_separations(
                    rot,
                    center,
                    self._box_half,
                    self._stock_partners(),
                    r_inv,
                    t_s,
                    lo,
                    hi,
                    len(tree.lo),
                    np.array(most, dtype=float),
                    _TREE_FRONTIER,
                    KERNEL_SLACK_MM,
                )
                return sep
            except Exception as e:  # numba could not compile or load it here: numpy
                KERNELS.fail(e)
        out = np.empty((len(transforms), len(self._stock_pairs)))
        for col, p in enumerate(self._stock_pairs):
            out[:, col] = tree.separation(*self._partner_box(boxes, slice(None), int(p)), most)
        return out

    def _names(self, pair: tuple[int, int] | None) -> tuple[str, str] | None:
        if pair is None:
            return None
        return (self._bodies[pair[0]].name, self._bodies[pair[1]].name)

    def _clearance_pairs(self, clearance_of: Collection[str] | None) -> np.ndarray:
        if clearance_of is None:
            return self._pairs
        wanted = set(clearance_of)
        b = self._bodies
        keep = [
            k
            for k, (i, j) in enumerate(self._pairs)
            if wanted & {b[i].name, b[i].kind, b[j].name, b[j].kind}
        ]
        return self._pairs[keep]

    def check(
        self,
        q: np.ndarray,
        clearance: bool = False,
        clearance_of: Collection[str] | None = None,
    ) -> CollisionResult:
        """Collisions of single configurations.

        Parameters
        ----------
        q : ndarray, shape (n, m) or (m,)
            Joint vectors, mm / rad, columns in ``machine.axis_names`` order.
        clearance : bool
            Also compute the smallest distance over the checked pairs (slower).
        clearance_of : collection of str, optional
            Count only pairs with a body of these names or kinds in the clearance, e.g.
            ``JOB_BODIES`` (tool and stock) to leave out gaps inside the machine.

        Returns
        -------
        CollisionResult

        Raises
        ------
        ValueError
            For joint vectors of the wrong shape or with NaN.
        """
        q = self._as_q(q)
        n = q.shape[0]
        pairs: list[tuple[int, int] | None] = [None] * n
        dist = np.full(n, np.nan)
        nearest: list[tuple[int, int] | None] = [None] * n
        near_pairs = self._clearance_pairs(clearance_of) if clearance else self._pairs[:0]
        first = self._first_pairs(q, kernels=KERNELS.get(n))
        hit = first[:, 0] >= 0
        for k in np.flatnonzero(hit).tolist():
            pairs[k] = (int(first[k, 0]), int(first[k, 1]))
        for start in range(0, n if clearance else 0, _CHUNK):
            rows = slice(start, min(start + _CHUNK, n))
            transforms = self._moving_transforms(q[rows])
            if clearance:
                bounds = self._lower_bounds(transforms, near_pairs)
                for k in range(transforms.shape[0]):
                    if hit[start + k]:
                        dist[start + k], nearest[start + k] = 0.0, pairs[start + k]
                    else:
                        self._set_moving(transforms[k])
                        d, arg = self._nearest(transforms[k], near_pairs, bounds[k])
                        dist[start + k], nearest[start + k] = d, arg
        return CollisionResult(
            hit=hit,
            pairs=[self._names(p) for p in pairs],
            clearance=dist if clearance else None,
            nearest=[self._names(p) for p in nearest] if clearance else None,
        )

    def sample_counts(
        self, q: np.ndarray, step_mm: float = DEFAULT_STEP_MM, step_deg: float = DEFAULT_STEP_DEG
    ) -> np.ndarray:
        """Number of intervals :meth:`check_moves` cuts each move into.

        The sampling rule: along a straight joint-space move the points of two bodies move,
        relative to each other, along paths no longer than ``s = sum_j lever_j * |dq_j|``
        (``lever_j`` = 1 for a linear axis, and for a rotary axis the largest distance of any
        body point from it, see :attr:`levers`). The move is cut into ``max(ceil(s / step_mm),
        ceil(max_rotary |dq| / step_deg), 1)`` equal intervals, so between two samples no body
        point moves more than ``step_mm`` relative to another body, and no rotary axis turns
        more than ``step_deg``.

        Parameters
        ----------
        q : ndarray, shape (n, m)
            mm / rad.
        step_mm : float
            mm.
        step_deg : float
            Degrees.

        Returns
        -------
        ndarray, shape (n - 1,), int
        """
        if not (step_mm > 0 and step_deg > 0):
            raise ValueError(f"expected positive steps, got {step_mm!r} mm, {step_deg!r} deg")
        q = self._as_q(q)
        dq = np.abs(np.diff(q, axis=0))
        swept = dq @ self._levers
        rot = [i for i, a in enumerate(self.machine.axes) if a.rotary]
        turn = dq[:, rot].max(axis=1) if rot else np.zeros(len(dq))
        n = np.maximum(np.ceil(swept / step_mm), np.ceil(turn / math.radians(step_deg)))
        return np.maximum(n, 1).astype(int)

    def _ends_and_moves(
        self, q: np.ndarray, kernels: ModuleType | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_first_pairs` of the configurations ``q`` (n, m), and the pairs that may come
        within ``GAP_MM`` somewhere on each straight joint-space move between consecutive ones,
        shape (n - 1, p), bool, from the same placements.

        Along a move no point of a body moves more than ``s = sum_j lever_j |dq_j|`` relative
        to another body (:meth:`sample_counts`), so a pair whose distance is at least ``b0`` at
        the start and ``b1`` at the end (the box gaps of :meth:`_lower_bounds`) keeps at least
        ``(b0 + b1 - s) / 2`` all along; a stock pair whose partner's box keeps ``GAP_MM + s``
        from every leaf box of the stock's tree at both ends cannot reach the stock's surface
        either (nor enter or leave it: whether a body is inside the stock is the same all
        along, and is checked at the ends). ``kernels`` (:data:`KERNELS`): the box gaps and
        the tree's descents compiled, each lowered by ``KERNEL_SLACK_MM`` (a move or pair more
        may be kept, none fewer).
        """
        pairs = self._pairs
        n = q.shape[0]
        swept = np.abs(np.diff(q, axis=0)) @ self._levers
        ends = np.full((n, 2), -1)
        bound = np.empty((n, len(pairs)))
        near_start = np.ones((max(n - 1, 0), len(pairs)), dtype=bool)
        near_end = np.ones_like(near_start)
        for start in range(0, n, _CHUNK):
            stop = min(start + _CHUNK, n)
            transforms = self._moving_transforms(q[start:stop])
            boxes = self._boxes(transforms)
            rows = np.arange(start, stop)
            starts, finishes = rows[rows < n - 1], rows[rows > 0]
            # box gaps where the gap of the axis-aligned boxes lets a move in or out pass
            adjacent = np.zeros(stop - start)
            adjacent[starts - start] = swept[starts]
            adjacent[finishes - start] = np.maximum(adjacent[finishes - start], swept[finishes - 1])
            here = self._lower_bounds(transforms, pairs, 2 * GAP_MM + adjacent, boxes, kernels)
            bound[start:stop] = here
            ask = here <= GAP_MM
            stock = self._stock_tree is not None and len(self._stock_pairs) > 0
            if not stock:
                ends[start:stop] = self._first_asked(transforms, ask)
                continue
            # the stock pairs: one descent of the stock's tree per configuration and pair
            # answers the gaps asked (the configuration's own, and either move's)
            sep = self._stock_separations(transforms, GAP_MM + adjacent, boxes, kernels)
            wide = _within(sep, GAP_MM + adjacent[:, None])  # within reach of either move
            ask[:, self._stock_pairs] &= wide & _within(sep, GAP_MM)
            ends[start:stop] = self._first_asked(transforms, ask)
            # each configuration as the start of its own move and the end of the one before
            sides = ((near_start, starts, starts), (near_end, finishes, finishes - 1))
            for mask, at, moves in sides:
                if len(at):
                    reach = _within(sep[at - start], GAP_MM + swept[moves][:, None])
                    mask[moves[:, None], self._stock_pairs[None, :]] = wide[at - start] & reach
        may = (bound[:-1] + bound[1:] - swept[:, None]) / 2 <= GAP_MM
        return ends, may & near_start & near_end

    def check_moves(
        self, q: np.ndarray, step_mm: float = DEFAULT_STEP_MM, step_deg: float = DEFAULT_STEP_DEG
    ) -> MoveCollisionResult:
        """Collisions along the straight joint-space moves between consecutive configurations.

        Each move is sampled as :meth:`sample_counts` says (both ends included) and scanned
        from its start; the scan of a move stops at its first collision. Anywhere on the move,
        the bodies are within ``step_mm / 2`` (relative displacement of any point) of where
        they are at the nearest sample, so an overlap that holds a ball of diameter
        ``step_mm / 2`` is always found; only shallower grazes can fall between samples.

        Parameters
        ----------
        q : ndarray, shape (n, m)
            Joint vectors, mm / rad.
        step_mm : float
            Largest displacement of a body point between samples, mm.
        step_deg : float
            Largest rotary axis change between samples, degrees.

        Returns
        -------
        MoveCollisionResult
        """
        q = self._as_q(q)
        counts = self.sample_counts(q, step_mm, step_deg)
        n_moves = q.shape[0] - 1
        # every sample once, in path order: each move's start and interior, then the last end
        move = np.repeat(np.arange(n_moves), counts)
        offsets = np.cumsum(counts) - counts
        k = np.arange(len(move)) - np.repeat(offsets, counts)
        first = np.full((len(move) + 1, 2), -1)
        # the move ends (the configurations themselves), then the interior samples of the moves
        # on which a pair can touch at all, only for those pairs (:meth:`_ends_and_moves`)
        kernels = KERNELS.get(len(move) + 1)
        ends, may = self._ends_and_moves(q, kernels)
        first[offsets] = ends[:-1]
        first[-1] = ends[-1]
        touching = np.asarray(may.any(axis=1), dtype=bool)  # moves on which a pair may touch
        inner = np.flatnonzero((k > 0) & touching[move])
        for lo in range(0, len(inner), _CHUNK):
            at = inner[lo : lo + _CHUNK]
            mv = move[at]
            t = k[at] / counts[mv]
            qs = q[mv] + t[:, None] * (q[mv + 1] - q[mv])
            first[at] = self._first_pairs(qs, allowed=may[mv], kernels=kernels)
        # per sample, the next colliding sample at or after it
        hits = np.flatnonzero(first[:, 0] >= 0)
        nxt = np.searchsorted(hits, offsets)
        found = nxt < len(hits)
        at_sample = np.full(n_moves, -1)
        at_sample[found] = hits[nxt[found]]
        hit = found & (at_sample <= offsets + counts)
        at = np.full(n_moves, np.nan)
        at[hit] = (at_sample[hit] - offsets[hit]) / counts[hit]
        pairs: list[tuple[str, str] | None] = [None] * n_moves
        for m in np.flatnonzero(hit):
            pairs[m] = self._names((int(first[at_sample[m], 0]), int(first[at_sample[m], 1])))
        return MoveCollisionResult(hit=hit, pairs=pairs, at=at, samples=counts)
