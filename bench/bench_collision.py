"""Benchmark of the collision checks: prints figures (no pass/fail; speed is never tested).

A five-axis zig-zag finishing path of 10,000 points over closed heightfield parts of about
10,000 and 100,000 triangles, on the shipped machines ``dmu50`` (table-table) and
``monoblock`` (head-table). Figures are microseconds per CL point (and per sample of the
moves): ``check`` of every point, ``check_moves`` of the whole path, the clearance.

The same path is then posted whole (TCP, Heidenhain) without and with the collision checks
(``--stock``): their cost per CL point is the difference. Issue 21's target: the checks of every
move against a 10k-triangle stock under 50 us per CL point.

The moves are timed in wall time and in this process's CPU time (``time.process_time``: the
figure to compare on a machine other work shares). With numba installed the box culling runs
compiled (``urdfpost.collision._kernels``); its one-off loading (numba's import, the cached
machine code: about 0.6 s of CPU per process) is timed and printed first, apart from the
figures per CL point.

Run: ``python bench/bench_collision.py`` (``--cells 71`` for the 10k case only).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

from urdfpost.collision import JOB_BODIES, CollisionWorld, ToolBody
from urdfpost.kinematics import inverse
from urdfpost.machine import load_machine
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import post
from urdfpost.toolpath import Event, Motion, Toolpath

TOOL_LENGTH = 100.0  # mm
SIZE = 120.0  # part side, mm


def height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Top surface of the part, mm (a wavy dome, 18 to 37 mm high)."""
    r2 = (x**2 + y**2) / (SIZE / 2) ** 2
    return 20.0 + 15.0 * np.clip(1.0 - r2, 0.0, None) + 2.0 * np.sin(x / 9.0) * np.cos(y / 13.0)


def heightfield_part(cells: int) -> trimesh.Trimesh:
    """Closed mesh: a heightfield top over a square, vertical walls and a flat bottom at z = 0.

    Parameters
    ----------
    cells : int
        Grid cells per side; the top has ``2 * cells**2`` triangles.
    """
    g = np.linspace(-SIZE / 2, SIZE / 2, cells + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    top = np.column_stack([x.ravel(), y.ravel(), height(x, y).ravel()])
    idx = np.arange((cells + 1) ** 2).reshape(cells + 1, cells + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = [np.column_stack([a, b, c]), np.column_stack([a, c, d])]
    # boundary loop (counter-clockwise seen from above) and the bottom copy of it
    loop = np.concatenate([idx[:, 0], idx[-1, 1:], idx[-2::-1, -1], idx[0, -2:0:-1]])
    n_top, n = len(top), len(loop)
    bottom = top[loop] * [1.0, 1.0, 0.0]
    k = np.arange(n)
    top_i, top_j = loop[k], loop[(k + 1) % n]
    bot_i, bot_j = n_top + k, n_top + (k + 1) % n
    faces += [np.column_stack([top_i, bot_i, bot_j]), np.column_stack([top_i, bot_j, top_j])]
    faces.append(np.column_stack([np.full(n - 2, n_top), n_top + k[2:], n_top + k[1:-1]]))
    mesh = trimesh.Trimesh(np.vstack([top, bottom]), np.vstack(faces), process=True)
    mesh.fix_normals()
    return mesh


def finishing_path(n_points: int, lines: int) -> tuple[np.ndarray, np.ndarray]:
    """Zig-zag path on the part top: tips (n, 3) mm and tool axes (n, 3).

    The tool axis is the surface normal plus twice a fixed direction 40 degrees from vertical
    toward -X (normalised), so both rotary axes move all the time and the tool stays at least
    15 degrees from vertical, clear of the pole.
    """
    per_line = n_points // lines
    span = 0.45 * SIZE
    xs = np.linspace(-span, span, per_line)
    ys = np.linspace(-span, span, lines)
    tips = []
    for i, y in enumerate(ys):
        x = xs if i % 2 == 0 else xs[::-1]
        tips.append(np.column_stack([x, np.full_like(x, y)]))
    xy = np.vstack(tips)
    h = 1e-3
    z = height(xy[:, 0], xy[:, 1])
    dzdx = (height(xy[:, 0] + h, xy[:, 1]) - height(xy[:, 0] - h, xy[:, 1])) / (2 * h)
    dzdy = (height(xy[:, 0], xy[:, 1] + h) - height(xy[:, 0], xy[:, 1] - h)) / (2 * h)
    normal = np.column_stack([-dzdx, -dzdy, np.ones_like(z)])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    lean = np.radians(40.0)
    axis = normal + 2.0 * np.array([-np.sin(lean), 0.0, np.cos(lean)])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return np.column_stack([xy, z]), axis


def joint_path(machine_name: str, tips: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Joint vectors along the path, shape (n, m): per point the IK branch within travel
    nearest the previous point, continuous axes unwrapped (a plain local choice)."""
    machine = load_machine(machine_name)
    ik = inverse(machine, tips, axes, TOOL_LENGTH)
    cand = ik.q  # (n, 2, m)
    inside = np.all((cand >= machine.lower - 1e-9) & (cand <= machine.upper + 1e-9), axis=2)
    rot = list(machine.rotary_columns)
    cont = [i for i, a in enumerate(machine.axes) if a.continuous]
    q = np.empty((len(tips), len(machine.axes)))
    prev = machine.home
    for i in range(len(tips)):
        c = cand[i].copy()
        c[:, cont] = prev[cont] + np.angle(np.exp(1j * (c[:, cont] - prev[cont])))
        step = np.where(inside[i], np.abs(c[:, rot] - prev[rot]).sum(axis=1), np.inf)
        prev = q[i] = c[int(np.argmin(step))]
    return q


def bench(machine_name: str, stock: Path, tips: np.ndarray, axes: np.ndarray) -> None:
    machine = load_machine(machine_name)
    q = joint_path(machine_name, tips, axes)
    if np.isnan(q).any():
        raise SystemExit(f"{machine_name}: the bench path is not reachable")
    t0 = time.perf_counter()
    world = CollisionWorld.build(machine, ToolBody(diameter=10.0), TOOL_LENGTH, stock)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = world.check(q)
    t_check = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), time.process_time()
    moves = world.check_moves(q, step_mm=1.0, step_deg=1.0)
    t_moves, c_moves = time.perf_counter() - t0, time.process_time() - c0
    k = 1000
    t0 = time.perf_counter()
    near = world.check(q[:k], clearance=True, clearance_of=JOB_BODIES)
    t_clear = (time.perf_counter() - t0) / k * len(q)
    samples = int(moves.samples.sum() + len(q))
    us = 1e6 / len(q)
    print(
        f"{machine_name:10s} {len(q):6d} {t_build:6.2f} {t_check * us:8.1f} {t_moves * us:8.1f} "
        f"{c_moves * us:8.1f} {samples:8d} {t_moves / samples * 1e6:7.2f} {t_clear * us:8.1f} "
        f"{int(res.hit.sum()):5d} {int(moves.hit.sum()):5d} {np.nanmin(near.clearance):7.2f}"
    )


def bench_post(machine_name: str, stock: Path, tips: np.ndarray, axes: np.ndarray) -> None:
    """The whole post (TCP, heidenhain, exact strategy) without and with the collision checks:
    every branch candidate at every point, the program's moves, the clearance at the CL points."""
    machine = load_machine(machine_name)
    n = len(tips)
    motion = np.full(n, Motion.FEED, dtype=np.int8)
    motion[0] = Motion.RAPID
    tp = Toolpath(
        tip=tips,
        axis=axes,
        feed=np.full(n, 2000.0),
        motion=motion,
        line=np.arange(1, n + 1),
        events=(Event(0, "cutter", 0, {"diameter": 10.0, "corner_radius": 0.0}),),
        source="bench",
    )
    times = []
    for options in (
        PostOptions(tool_length=TOOL_LENGTH, strategy="recursive", spindle=10000.0),
        PostOptions(
            tool_length=TOOL_LENGTH, strategy="recursive", spindle=10000.0, stock=str(stock)
        ),
    ):
        t0 = time.perf_counter()
        result = post(tp, machine, options)
        times.append(time.perf_counter() - t0)
    hits = result.report.as_json()["collisions"]
    us = 1e6 / n
    print(
        f"{machine_name:10s} {n:6d} {times[0]:8.2f} {times[1]:8.2f} {times[0] * us:8.1f} "
        f"{(times[1] - times[0]) * us:8.1f} {times[1] / times[0]:6.2f} {hits['samples']:8d} "
        f"{hits['min_clearance']:7.2f} ({hits['clearance_points']} points)"
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--cells",
        type=int,
        nargs="+",
        default=[71, 224],
        help="grid cells per side of each part: 71 = about 10k triangles, 224 = about 100k",
    )
    parser.add_argument("--no-post", action="store_true", help="skip the whole posts")
    args = parser.parse_args(argv)
    try:
        from urdfpost.collision.world import warm_kernels
    except ImportError:  # a tree from before the compiled culling
        print("compiled culling: not in this tree")
    else:
        t0, c0 = time.perf_counter(), time.process_time()
        loaded = warm_kernels()
        print(
            f"compiled culling: {'loaded' if loaded else 'unavailable (numpy path)'} in "
            f"{time.perf_counter() - t0:.2f} s ({time.process_time() - c0:.2f} s CPU), once"
        )
    tips, axes = finishing_path(10_000, 50)
    for cells in args.cells:
        part = heightfield_part(cells)
        print(
            f"\npart: {len(part.faces)} triangles, closed: {part.is_watertight}; path: "
            f"{len(tips)} points; tool 10 mm x {TOOL_LENGTH:g} mm, holder 40 x 60 mm; "
            f"cores: {os.cpu_count()}"
        )
        print(
            "machine    points  build    check    moves   moves  samples  us/smp   clear*  hits "
            "mhits min clr"
        )
        print(
            "                    s    us/pt    us/pt  cpu us/pt (moves)             us/pt        "
            "     mm"
        )
        with tempfile.TemporaryDirectory() as tmp:
            stock = Path(tmp) / "part.stl"
            part.export(stock)
            for name in ("dmu50", "monoblock"):
                bench(name, stock, tips, axes)
            print(
                "* clearance of the tool and the stock at every point, extrapolated from the "
                "first 1,000 points; min clr over those"
            )
            if args.no_post:
                continue
            print("\nfull post without and with collision checks (--stock)")
            print("machine    points  plain s  stock s  plain    checks  ratio  samples min clr mm")
            print("                                     us/pt    us/pt")
            for name in ("dmu50", "monoblock"):
                bench_post(name, stock, tips, axes)


if __name__ == "__main__":
    main()
