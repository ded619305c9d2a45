"""Scaling benchmark: posting speed and memory against the numpy floor and numerical IK.

Run::

    python bench/bench_scale.py                          # 100k and 1M points
    python bench/bench_scale.py --quick                  # 20k and 200k points
    python bench/bench_scale.py --sizes 100000,1000000 --controls fanuc,heidenhain

For each size a hemisphere job (``bench/make_large_cl.py``, tool axis varying, passes over and
beside the pole) is written once to the temporary directory. Every figure comes from its own
subprocess, so peak memories (``ru_maxrss`` of that process, imports included; the "base"
column is the peak after the imports, before the work) do not pollute each other:

(a) ``read``: :func:`urdfpost.read_cl` of the file;
(b) ``post mc``: read + :func:`urdfpost.post` in machine coordinates (branch choice, pole
    handling, linearisation, the NC text, read back and verified);
(c) ``post tcp``: the same with TCP output;
    (b) and (c) for the fastest and the slowest control (a probe times the write + read back of
    one program in each control first, unless ``--controls`` names them);
(d) ``floor``: the numbers of the GOTO records read with numpy from the same file (the fastest
    of ``np.loadtxt`` and a regex + ``np.fromstring``);
(e) ``numerical IK``: per-point damped least squares with Pinocchio on the tool pose relative to
    the workpiece (position and tool axis), warm-started from the previous point, as one would
    write it without a closed-form solver; a sample of points, extrapolated to the file;
(f) ``closed-form IK``: :func:`urdfpost.kinematics.inverse.inverse` over all points of the file;
(g) ``in pieces``: (b) and (c) as ``urdfpost post`` runs them on large files
    (:func:`urdfpost.posting.stream.post_stream` over
    :func:`urdfpost.readers.read_cl_chunks`, pieces of :data:`urdfpost.posting.PIECE_POINTS` CL
    points, each verified in a worker process while the next is planned: the two cores share
    the work); the worker's peak memory is shown beside the post's. Then the fastest control
    in machine coordinates at 10M points as well (``--stream-sizes``): the peak memory must not grow
    with the job;
(h) ``urdfpost verify`` of the program of (b) for the fastest control (posted once and kept
    beside the CL file), whole and in pieces (:func:`urdfpost.posting.readback.verify_stream`); in
    pieces at 10M too.

Printed ratios: post over floor, numerical over closed-form IK per point, and the growth of
time with size. Nothing here is a test: speed is never checked in the suite.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))  # oracles.py

from make_large_cl import ensure_file  # noqa: E402

MACHINE = "dmu50"
CONTROLS = ("heidenhain", "siemens", "fanuc", "linuxcnc")
PIN_SAMPLE = 200  # points of the numerical IK sample
PIN_RUNS = 4  # the sample is this many runs of consecutive points (warm starts within a run)


# -- measurements, each run in a child process ---------------------------------------------------


def _peak_mb() -> float:
    """Peak resident memory of this process so far, MB (Linux ru_maxrss is in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def measure_read(path: str) -> dict[str, Any]:
    from urdfpost import read_cl

    base = _peak_mb()
    t = time.perf_counter()
    toolpath = read_cl(path)
    dt = time.perf_counter() - t
    return {"seconds": dt, "points": len(toolpath), "base_mb": base}


def measure_post(path: str, control: str, tcp: bool) -> dict[str, Any]:
    from urdfpost import PostOptions, load_machine, post, read_cl

    machine = load_machine(MACHINE)
    base = _peak_mb()
    t = time.perf_counter()
    toolpath = read_cl(path)
    t_read = time.perf_counter() - t
    result = post(toolpath, machine, PostOptions(controller=control, tcp=tcp))
    dt = time.perf_counter() - t
    v = result.verification
    return {
        "seconds": dt,
        "read_seconds": t_read,
        "points": len(toolpath),
        "blocks": v.blocks,
        "text_mb": len(result.text) / 1e6,
        "max_dev_mm": v.max_tip_deviation,
        "ok": v.ok,
        "base_mb": base,
    }


def measure_stream(path: str, control: str, tcp: bool) -> dict[str, Any]:
    """The post of (b)/(c) in pieces (:func:`urdfpost.posting.stream.post_stream`, the file read
    with :func:`urdfpost.readers.read_cl_chunks`, each piece verified in a worker process while the
    next is planned), the program written to a temporary file."""
    import tempfile

    from urdfpost import PostOptions, load_machine
    from urdfpost.posting import PIECE_POINTS
    from urdfpost.posting.stream import post_stream
    from urdfpost.readers import read_cl_chunks

    machine = load_machine(MACHINE)
    base = _peak_mb()
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "program.nc"
        t = time.perf_counter()
        pieces = read_cl_chunks(path, max_points=PIECE_POINTS)
        options = PostOptions(controller=control, tcp=tcp)
        result = post_stream(pieces, machine, out, options, piece_points=PIECE_POINTS)
        dt = time.perf_counter() - t
        text_mb = out.stat().st_size / 1e6
    v = result.verification
    return {
        "seconds": dt,
        "points": v.cl_points,
        "blocks": v.blocks,
        "text_mb": text_mb,
        "max_dev_mm": v.max_tip_deviation,
        "ok": v.ok,
        "pieces": result.report.as_json()["streamed"]["pieces"],
        "piece_points": PIECE_POINTS,
        "base_mb": base,
        # the verification worker's peak (its RSS shares the pages forked from this process)
        "worker_peak_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0,
    }


def floor_loadtxt(path: str) -> np.ndarray:
    """GOTO values with ``np.loadtxt`` on the GOTO lines, shape (n, 6)."""
    with open(path, encoding="ascii") as handle:
        lines = (line[5:] for line in handle if line.startswith("GOTO/"))
        return np.loadtxt(lines, delimiter=",", ndmin=2)


def floor_fromstring(path: str) -> np.ndarray:
    """GOTO values with one regex over the file and ``np.fromstring``, shape (n, 6)."""
    with open(path, "rb") as handle:
        data = handle.read()
    numbers = b",".join(re.findall(rb"^GOTO/([^\r\n]*)", data, re.M))
    return np.fromstring(numbers.decode("ascii"), sep=",").reshape(-1, 6)


def measure_floor(path: str) -> dict[str, Any]:
    base = _peak_mb()
    best, name, count = np.inf, "", 0
    for fn in (floor_fromstring, floor_loadtxt):
        t = time.perf_counter()
        values = fn(path)
        dt = time.perf_counter() - t
        if dt < best:
            best, name, count = dt, fn.__name__, len(values)
        del values
    return {"seconds": best, "points": count, "method": name, "base_mb": base}


def measure_closed_form_ik(path: str) -> dict[str, Any]:
    from urdfpost import load_machine, read_cl
    from urdfpost.kinematics.inverse import inverse

    machine = load_machine(MACHINE)
    toolpath = read_cl(path)
    base = _peak_mb()
    tool_length = machine.settings.tool_length
    inverse(machine, toolpath.tip[:1000], toolpath.axis[:1000], tool_length)  # warm up
    best = np.inf
    for _ in range(3):
        t = time.perf_counter()
        result = inverse(machine, toolpath.tip, toolpath.axis, tool_length)
        best = min(best, time.perf_counter() - t)
        del result
    return {"seconds": best, "points": len(toolpath), "base_mb": base}


def numerical_ik(
    urdf: str, tip: np.ndarray, axis: np.ndarray, tool_length: float, runs: int
) -> tuple[np.ndarray, np.ndarray, int]:
    """Per-point damped least squares IK with Pinocchio, as written without a closed form.

    The task is the tool frame relative to the workpiece frame: its origin (the gauge point,
    ``tool_length`` above the tip along the axis) and its +Z axis (5 conditions; the spin
    about the tool axis is free), solved by Gauss-Newton steps with a little damping on the
    6 x 5 Jacobian of (origin, +Z) from Pinocchio's frame Jacobians. Each point starts from the
    previous solution; the first point of each of ``runs`` equal runs starts from the home
    configuration.

    Parameters
    ----------
    urdf : str
        Machine URDF file (metres).
    tip, axis : ndarray, shape (k, 3)
        Tool tips (mm) and unit tool axes in the workpiece frame.
    tool_length : float, mm

    Returns
    -------
    q : ndarray, shape (k, nq)
        Pinocchio configurations.
    iterations : ndarray, shape (k,), int
        Gauss-Newton steps per point.
    failures : int
        Points not converged within the iteration limit.
    """
    import pinocchio as pin

    model = pin.buildModelFromUrdf(urdf)
    data = model.createData()
    fw, ft = model.getFrameId("workpiece"), model.getFrameId("tool")
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    damping = 1e-12
    eps = 1e-9  # m and rad
    max_iter = 200
    home = pin.neutral(model)
    k = len(tip)
    qs = np.empty((k, model.nq))
    iterations = np.zeros(k, dtype=int)
    failures = 0
    starts = set(np.linspace(0, k, runs, endpoint=False).astype(int).tolist())
    q = home
    for i in range(k):
        if i in starts:
            q = home.copy()
        p_target = (tip[i] + tool_length * axis[i]) / 1000.0
        z_target = axis[i]
        steps = 0
        for steps in range(max_iter):  # noqa: B007 (the count is reported)
            pin.framesForwardKinematics(model, data, q)
            o_m_w, o_m_t = data.oMf[fw], data.oMf[ft]
            w_m_t = o_m_w.actInv(o_m_t)
            z = w_m_t.rotation[:, 2]
            err = np.concatenate([p_target - w_m_t.translation, z_target - z])
            if np.linalg.norm(err) < eps:
                break
            pin.computeJointJacobians(model, data, q)
            j_t = pin.getFrameJacobian(model, data, ft, lwa)
            j_w = pin.getFrameJacobian(model, data, fw, lwa)
            r_w = o_m_w.rotation
            arm = o_m_t.translation - o_m_w.translation
            j_v = r_w.T @ (j_t[:3] - j_w[:3] + pin.skew(arm) @ j_w[3:])
            j_z = -pin.skew(z) @ r_w.T @ (j_t[3:] - j_w[3:])  # dz = omega x z
            jac = np.vstack([j_v, j_z])
            dq = np.linalg.solve(jac.T @ jac + damping * np.eye(model.nv), jac.T @ err)
            q = pin.integrate(model, q, dq)
        else:
            failures += 1
        qs[i] = q
        iterations[i] = steps
    return qs, iterations, failures


def measure_numerical_ik(path: str) -> dict[str, Any]:
    from oracles import tip_and_axis_pin  # tests/oracles.py

    from urdfpost import load_machine, read_cl

    machine = load_machine(MACHINE)
    toolpath = read_cl(path)
    base = _peak_mb()
    n = len(toolpath)
    per_run = PIN_SAMPLE // PIN_RUNS
    firsts = np.linspace(0, n - per_run, PIN_RUNS).astype(int)
    index = np.concatenate([np.arange(s, s + per_run) for s in firsts])
    tool_length = machine.settings.tool_length
    tip, axis = toolpath.tip[index], toolpath.axis[index]
    t = time.perf_counter()
    qs, iterations, failures = numerical_ik(str(machine.path), tip, axis, tool_length, PIN_RUNS)
    dt = time.perf_counter() - t
    # check the answers with urdfpost's Pinocchio forward kinematics
    q = np.column_stack([qs[:, :4], np.arctan2(qs[:, 5], qs[:, 4])])  # X Y Z B, C from cos/sin
    q[:, :3] *= 1000.0
    got_tip, got_axis = tip_and_axis_pin(machine, q, tool_length)
    return {
        "seconds": dt,
        "points": len(index),
        "file_points": n,
        "mean_iterations": float(iterations.mean()),
        "failures": failures,
        "max_tip_error_mm": float(np.max(np.linalg.norm(got_tip - tip, axis=1))),
        "max_axis_error": float(np.max(np.linalg.norm(got_axis - axis, axis=1))),
        "base_mb": base,
    }


def _program_of(path: str, control: str) -> Path:
    """The program of CL file ``path`` for ``control`` in machine coordinates, posted once (by
    ``urdfpost post``, in pieces) and kept beside it."""
    program = Path(path).with_suffix(f".{control}.nc")
    if not program.exists():
        cmd = [sys.executable, "-m", "urdfpost", "post", path, "-m", MACHINE, "-c", control]
        subprocess.run([*cmd, "--no-tcp", "-q", "-o", str(program)], check=True)
    return program


def measure_verify(path: str, control: str, pieces: bool) -> dict[str, Any]:
    """``urdfpost verify`` of the program of (b) against its CL file: whole (the program and
    the CL data read at once) or in pieces (:func:`urdfpost.posting.readback.verify_stream`)."""
    from urdfpost import load_machine, read_cl
    from urdfpost.dialects import dialect_for
    from urdfpost.posting import PIECE_POINTS
    from urdfpost.posting.check import ball_radius, bent_tolerances
    from urdfpost.posting.readback import verify_stream
    from urdfpost.readers import read_cl_chunks
    from urdfpost.tolerances import Tolerances
    from urdfpost.verification import verify

    program_path = _program_of(path, control)
    machine = load_machine(MACHINE)
    dialect = dialect_for(control)
    length = machine.settings.tool_length
    base = _peak_mb()
    t = time.perf_counter()
    if pieces:
        chunks = read_cl_chunks(path, max_points=PIECE_POINTS)
        first = next(chunks)
        pivot = ball_radius(first)
        tol = bent_tolerances(Tolerances.for_units("mm"), 2.0, pivot)
        v, _ = verify_stream(
            program_path,
            itertools.chain([first], chunks),
            machine,
            control,
            tol=tol,
            tool_length=length,
            pivot=pivot,
        )
    else:
        program = dialect.read(program_path.read_text(encoding="utf-8"), path=str(program_path))
        toolpath = read_cl(path)
        pivot = ball_radius(toolpath)
        tol = bent_tolerances(Tolerances.for_units("mm"), 2.0, pivot)
        v = verify(program, machine, toolpath, tool_length=length, tol=tol, pivot=pivot)
    dt = time.perf_counter() - t
    return {
        "seconds": dt,
        "points": v.cl_points,
        "blocks": v.blocks,
        "max_dev_mm": v.max_tip_deviation,
        "ok": v.ok,
        "base_mb": base,
    }


def measure_dialects(path: str) -> dict[str, Any]:
    """Write + read back time of one machine-coordinate program in every control."""
    from urdfpost import PostOptions, load_machine, post, read_cl
    from urdfpost.dialects import dialect_for

    machine = load_machine(MACHINE)
    program = post(read_cl(path), machine, PostOptions(tcp=False)).program
    seconds = {}
    for name in CONTROLS:
        dialect = dialect_for(name)
        best = np.inf
        for _ in range(3):
            t = time.perf_counter()
            dialect.read(dialect.write(program))
            best = min(best, time.perf_counter() - t)
        seconds[name] = best
    return {"seconds": min(seconds.values()), "per_control": seconds, "points": len(program.blocks)}


def child(kind: str, path: str, control: str, tcp: bool) -> None:
    """Run one measurement and print its figures as one JSON line."""
    if kind == "read":
        out = measure_read(path)
    elif kind == "post":
        out = measure_post(path, control, tcp)
    elif kind == "stream":
        out = measure_stream(path, control, tcp)
    elif kind == "floor":
        out = measure_floor(path)
    elif kind == "ik":
        out = measure_closed_form_ik(path)
    elif kind == "pin":
        out = measure_numerical_ik(path)
    elif kind == "dialects":
        out = measure_dialects(path)
    elif kind in ("verify", "verify-pieces"):
        out = measure_verify(path, control, kind == "verify-pieces")
    else:
        raise ValueError(kind)
    out["peak_mb"] = _peak_mb()
    print(json.dumps(out))


# -- the parent: runs the children and prints the table ------------------------------------------


def run_child(
    kind: str, path: Path, timeout: float, control: str = "", tcp: bool = False
) -> dict[str, Any]:
    """Figures of one measurement in a fresh interpreter (``{"error": ...}`` on failure)."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--child", kind, "--path", str(path)]
    if control:
        cmd += ["--control", control]
    if tcp:
        cmd.append("--tcp")
    t = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return {"error": f"timeout after {timeout:.0f} s"}
    wall = time.perf_counter() - t
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["?"])[-1]
        return {"error": f"exit {proc.returncode}: {tail}"}
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["wall"] = wall
    return out


def _fmt_rate(points: float, seconds: float) -> str:
    rate = points / seconds
    return f"{rate / 1e6:9.2f} M" if rate >= 1e6 else f"{rate / 1e3:9.1f} k"


def print_row(label: str, res: dict[str, Any], points: int, note: str = "") -> None:
    """One line of the table: time, CL points/s, peak and base memory."""
    if "error" in res:
        print(f"  {label:<34} {res['error']}")
        return
    seconds = res["seconds"]
    print(
        f"  {label:<34} {seconds:9.3f} {_fmt_rate(points, seconds)} "
        f"{res['peak_mb']:9.0f} {res.get('base_mb', float('nan')):7.0f}  {note}"
    )


def _stream_note(r: dict[str, Any], floor: dict[str, Any] | None) -> str:
    """The figures of a streamed post after its time and memory."""
    if "error" in r:
        return ""
    ratio = (
        ""
        if floor is None or "error" in floor
        else f"{r['seconds'] / floor['seconds']:.0f}x floor; "
    )
    return (
        f"{ratio}worker peak {r['worker_peak_mb']:.0f} MB, {r['pieces']} pieces of "
        f"{r['piece_points'] // 1000}k, {r['blocks']} blocks, max dev {r['max_dev_mm']:.4f} mm, "
        f"verified {r['ok']}"
    )


def pick_controls(path: Path, timeout: float) -> tuple[str, str]:
    """Fastest and slowest control by the write + read back time of one program."""
    res = run_child("dialects", path, timeout)
    if "error" in res:
        print(f"control probe failed ({res['error']}); using heidenhain and fanuc")
        return "heidenhain", "fanuc"
    per = res["per_control"]
    print(
        f"control probe ({res['points']} blocks, write + read back, s): "
        + ", ".join(f"{k} {v:.3f}" for k, v in sorted(per.items(), key=lambda kv: kv[1]))
    )
    ranked = sorted(per, key=per.get)
    return ranked[0], ranked[-1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="100000,1000000", help="CL points, comma-separated")
    parser.add_argument("--quick", action="store_true", help="sizes 20000,200000")
    parser.add_argument("--controls", help="two controls, fastest first (default: probed)")
    parser.add_argument(
        "--timeout", type=float, default=1800.0, help="per measurement, s (default 1800)"
    )
    parser.add_argument("--no-post", action="store_true", help="skip (b) and (c), the full posts")
    parser.add_argument(
        "--stream-sizes",
        default="10000000",
        help="CL points of more streamed posts (g), comma-separated; '' for none",
    )
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--path", help=argparse.SUPPRESS)
    parser.add_argument("--control", default="", help=argparse.SUPPRESS)
    parser.add_argument("--tcp", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child(args.child, args.path, args.control, args.tcp)
        return 0

    sizes = [20_000, 200_000] if args.quick else [int(s) for s in args.sizes.split(",")]
    paths = {}
    for n in sizes:
        t = time.perf_counter()
        paths[n] = ensure_file(n)
        size_mb = paths[n].stat().st_size / 1e6
        print(f"{paths[n]}: {n} CL points, {size_mb:.1f} MB ({time.perf_counter() - t:.1f} s)")
    print(
        f"python {sys.version.split()[0]}, numpy {np.__version__}, {os.cpu_count()} CPUs, "
        f"load average {os.getloadavg()[0]:.1f} at the start"
    )
    if args.controls:
        fast, slow = args.controls.split(",")
    elif args.no_post:
        fast = slow = ""
    else:
        fast, slow = pick_controls(paths[sizes[0]], args.timeout)
    controls = [fast] if fast == slow else [fast, slow]

    results: dict[int, dict[str, dict[str, Any]]] = {}
    for n in sizes:
        path = paths[n]
        res: dict[str, dict[str, Any]] = {}
        print(f"\n{n} CL points ({path.name}), load average {os.getloadavg()[0]:.1f}")
        print(f"  {'measurement':<34} {'time s':>9} {'CL pts/s':>11} {'peak MB':>9} {'base':>7}")
        res["read"] = run_child("read", path, args.timeout)
        print_row("(a) read_cl", res["read"], n)
        res["floor"] = run_child("floor", path, args.timeout)
        print_row("(d) floor: numpy", res["floor"], n, res["floor"].get("method", ""))
        if not args.no_post:
            for tcp in (False, True):
                for control in controls:
                    key = f"post {'tcp' if tcp else 'mc'} {control}"
                    res[key] = r = run_child("post", path, args.timeout, control, tcp)
                    label = f"({'c' if tcp else 'b'}) post {'TCP' if tcp else 'machine'} {control}"
                    note = ""
                    if "error" not in r:
                        ratio = r["seconds"] / res["floor"]["seconds"]
                        note = (
                            f"{ratio:.0f}x floor; read {r['read_seconds']:.2f} s, "
                            f"{r['blocks']} blocks, {r['text_mb']:.0f} MB text, "
                            f"max dev {r['max_dev_mm']:.4f} mm"
                        )
                    print_row(label, r, n, note)
            for tcp in (False, True):
                for control in controls:
                    key = f"streamed {'tcp' if tcp else 'mc'} {control}"
                    res[key] = r = run_child("stream", path, args.timeout, control, tcp)
                    label = f"(g) in pieces, {'TCP' if tcp else 'machine'} {control}"
                    print_row(label, r, n, _stream_note(r, res["floor"]))
            for kind in ("verify", "verify-pieces"):
                res[f"{kind} {fast}"] = r = run_child(kind, path, args.timeout, fast)
                label = f"(h) urdfpost verify, {'in pieces' if kind != 'verify' else 'whole'}"
                note = ""
                if "error" not in r:
                    note = (
                        f"{fast}, machine coordinates; {r['blocks']} blocks, "
                        f"max dev {r['max_dev_mm']:.4f} mm, verified {r['ok']}"
                    )
                print_row(label, r, n, note)
        res["ik"] = run_child("ik", path, args.timeout)
        print_row("(f) closed-form IK, all branches", res["ik"], n)
        res["pin"] = r = run_child("pin", path, args.timeout)
        if "error" in r:
            print_row("(e) numerical IK (Pinocchio DLS)", r, n)
        else:
            per_point = r["seconds"] / r["points"]
            extrapolated = {**r, "seconds": per_point * n}
            note = (
                f"{r['points']} pts sampled, {r['mean_iterations']:.1f} iterations/pt, "
                f"{r['failures']} not converged, max tip error {r['max_tip_error_mm']:.1e} mm"
            )
            print_row("(e) numerical IK, extrapolated", extrapolated, n, note)
            if "error" not in res["ik"]:
                ratio = per_point / (res["ik"]["seconds"] / n)
                print(f"  closed-form IK is {ratio:.0f}x faster per point than numerical IK")
        results[n] = res

    streamed = [int(x) for x in args.stream_sizes.split(",") if x.strip()]
    if streamed and fast:
        print(f"\n(g) in pieces, machine coordinates, {fast}: memory as the job grows")
        print(f"  {'CL points':<34} {'time s':>9} {'CL pts/s':>11} {'peak MB':>9} {'base':>7}")
        peaks = {
            n: results[n][f"streamed mc {fast}"]
            for n in sizes
            if "error" not in results[n].get(f"streamed mc {fast}", {"error": "-"})
        }
        for n in sorted({*peaks, *streamed}):
            r = peaks.get(n) or run_child("stream", ensure_file(n), args.timeout, fast, False)
            print_row(f"{n}", r, n, _stream_note(r, None))
            if "error" not in r:
                peaks[n] = r
            if n not in results:  # and its program checked again, in pieces
                v = run_child("verify-pieces", ensure_file(n), args.timeout, fast)
                note = "" if "error" in v else f"max dev {v['max_dev_mm']:.4f} mm, ok {v['ok']}"
                print_row(f"{n}: (h) verify in pieces", v, n, note)
        if len(peaks) > 1:  # the two largest jobs
            a, b = sorted(peaks)[-2:]

            def total(r: dict[str, Any]) -> float:
                return r["peak_mb"] + r["worker_peak_mb"]

            print(
                f"  peak memory (post + worker) {b} / {a} points: "
                f"{total(peaks[b]) / total(peaks[a]):.2f}x (points ratio {b / a:g})"
            )

    print(f"\nload average {os.getloadavg()[0]:.1f} at the end (other processes skew times)")
    if len(sizes) > 1:
        a, b = sizes[0], sizes[-1]
        print(f"\ngrowth: time({b}) / time({a}) (points ratio {b / a:g})")
        for key in results[a]:
            ra, rb = results[a][key], results[b].get(key, {"error": "-"})
            if key == "pin" or "error" in ra or "error" in rb:
                continue
            print(f"  {key:<34} {rb['seconds'] / ra['seconds']:6.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
