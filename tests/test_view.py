"""The 3-D view (issue 20): its data checked against the kinematics, the command line, and the
page itself opened in headless Chromium (Debian's ``chromium``; ``.ci/run`` installs it).

Without ``chromium`` on the PATH the browser tests are skipped, except in CI (``CI=true``),
where a missing browser is a failure.
"""

from __future__ import annotations

import base64
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from urdfpost.analysis.view import move_lines, program_rows, view_data, view_html
from urdfpost.cli import main
from urdfpost.dialects import dialect_for
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.machine import load_machine
from urdfpost.readers import read_cl

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
DOME = EXAMPLES / "dome.apt"
STOCK = EXAMPLES / "dome.stl"
CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


def _array(text: str, dtype: str, shape: tuple[int, ...]) -> np.ndarray:
    return np.frombuffer(base64.b64decode(text), dtype=dtype).reshape(shape)


@pytest.fixture(scope="module")
def dome_posts(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The dome job posted on dmu50 in TCP (Heidenhain) and machine coordinates (Fanuc)."""
    folder = tmp_path_factory.mktemp("view")
    out = {"tcp": folder / "dome.h", "machine": folder / "dome.nc"}
    assert main(["post", str(DOME), "-m", "dmu50", "-o", str(out["tcp"]), "-q"]) == 0
    assert (
        main(["post", str(DOME), "-m", "dmu50", "--no-tcp", "-o", str(out["machine"]), "-q"]) == 0
    )
    return out


def _data(path: Path, **kw: object) -> tuple[dict, object, object]:
    machine = load_machine("dmu50")
    dialect = dialect_for(None, str(path))
    text = path.read_text()
    program = dialect.read(text, path=str(path))
    data = view_data(machine, program, text, dialect, cl=read_cl(str(DOME)), **kw)  # type: ignore[arg-type]
    return data, machine, program


@pytest.mark.parametrize("mode", ["tcp", "machine"])
def test_samples_hold_the_program_rows_and_agree_with_pinocchio(
    dome_posts: dict[str, Path], mode: str
) -> None:
    """At the last sample of each move the tool tip is the program's own row (TCP: the
    programmed tip; machine coordinates: the tip the written joints give), and the tool and
    workpiece links Pinocchio placed carry that tip: two kinematics agree."""
    data, machine, program = _data(dome_posts[mode], stock=STOCK)
    n = data["samples"]
    tip = _array(data["tip"], "<f4", (n, 3)).astype(float)
    move = _array(data["move"], "<i4", (n,))
    t = _array(data["t"], "<f8", (n,))
    assert np.all(np.diff(t) >= 0) and t[-1] > 0
    ends = np.flatnonzero(np.diff(np.append(move, -1)) != 0)  # last sample of each move
    assert move[ends].tolist() == list(range(data["moves"]))
    tool_length = machine.settings.tool_length  # what verify takes (no --tool-length)
    q, _, _ = program_rows(machine, program, tool_length)
    expected, _ = tip_and_axis(machine, q, tool_length)
    if program.tcp:  # the programmed tip itself (forward-filled words)
        table = program.move_table().position
        cols = [program.axes.index(a) for a in ("X", "Y", "Z")]
        written = table[:, cols]
        ok = ~np.isnan(written).any(axis=1)
        assert np.allclose(expected[ok], written[ok], atol=1e-6)
    assert np.allclose(tip[ends], expected, atol=1e-2)  # (float32 in the page)
    # every CL point is reached by a move end: at the ball centre, as the post checks a bent
    # (cone) program, within the post's tolerance (0.0362 mm) and the page's float32
    cl = read_cl(str(DOME))
    axis_end = _array(data["axis"], "<f4", (n, 3)).astype(float)[ends]
    centre = tip[ends] + 3.0 * axis_end
    wanted = cl.tip + 3.0 * cl.axis
    gap = np.linalg.norm(wanted[:, None, :] - centre[None, :, :], axis=2).min(axis=1)
    assert gap.max() < 0.0362 + 1e-3, gap.max()
    # the tool link's pose (Pinocchio) against the tip trace in the workpiece frame (POE)
    links = data["moving"]
    poses = _array(data["poses"], "<f4", (n, len(links), 7)).astype(float)
    assert "workpiece" in links
    tool_links = [lk for lk in links if lk.startswith("tool") or lk == "spindle"]
    assert tool_links
    import pinocchio as pin

    def placement(k: int, i: int) -> np.ndarray:
        p = poses[i, k]
        return pin.XYZQUATToSE3(np.r_[p[:3] / 1000.0, p[3:]]).homogeneous

    w = links.index("workpiece")
    model = machine.model
    data_ = model.createData()
    tool_frame = model.getFrameId("tool")
    for i in np.linspace(0, n - 1, 25).astype(int):
        samples_q = _array(data["q"], "<f4", (n, len(data["axes"])))
        del samples_q  # (display values: degrees; checked against the poses below)
        # the tool frame's origin from the link poses, through the workpiece pose
        world_work = placement(w, i)
        pin.forwardKinematics(model, data_, machine.pin_configuration(_q_of(machine, data, i)))
        tool_world = pin.updateFramePlacement(model, data_, tool_frame).homogeneous
        gauge = (np.linalg.inv(world_work) @ tool_world)[:3, 3] * 1000.0
        axis = (np.linalg.inv(world_work) @ tool_world)[:3, 2]
        assert np.allclose(gauge - tool_length * axis, tip[i], atol=0.05), i


def _q_of(machine: object, data: dict, i: int) -> np.ndarray:
    """Joint values of sample ``i`` from the page's display values (degrees, program units)."""
    n, m = data["samples"], len(data["axes"])
    shown = _array(data["q"], "<f4", (n, m))[i].astype(float)
    return np.where(data["rotary"], np.radians(shown), shown)


def test_marks_and_lines(dome_posts: dict[str, Path]) -> None:
    """The dome's pole is marked, and so is its worst deviation; every move has its NC line,
    and that line is a motion block of the program."""
    data, _, _ = _data(dome_posts["tcp"])
    kinds = [m["kind"] for m in data["marks"]]
    assert "singular" in kinds and kinds.count("worst") == 1
    text = dome_posts["tcp"].read_text().splitlines()
    dialect = dialect_for(None, str(dome_posts["tcp"]))
    lines = move_lines(dialect, "\n".join(text) + "\n", "dome.h")
    assert len(lines) == data["moves"]
    assert all(re.search(r"\b(L|X|Y|Z|B|C)[+-]?\d", text[k - 1]) for k in lines.tolist())
    assert np.all(np.diff(lines) >= 0)
    for k, shown in data["text"].items():
        assert text[int(k) - 1] == shown


@pytest.mark.parametrize("mode", ["tcp", "machine"])
def test_move_lines_are_those_of_reading_line_by_line(
    dome_posts: dict[str, Path], mode: str
) -> None:
    """The reader's note of each move's line agrees with feeding the text one line at a time
    and counting the moves each line gives (the slow, obvious way)."""
    path = dome_posts[mode]
    dialect = dialect_for(None, str(path))
    text = path.read_text()
    reader = dialect.reader(str(path))
    slow: list[int] = []
    for number, line in enumerate(text.splitlines(keepends=True), start=1):
        reader.feed(line)
        slow += [number] * len(reader.take().move_table())
    assert move_lines(dialect, text, str(path)).tolist() == slow


def test_rewind_marked(tmp_path: Path) -> None:
    """A job whose C travel runs out rewinds; the rewind is marked on the timeline."""
    cl = tmp_path / "wind.apt"
    rows = ["UNITS/MM", "LOADTL/1", "SPINDL/1000,CLW", "FEDRAT/500"]
    for k in range(60):  # the tool axis circles the vertical 3 times: C winds 1080 deg
        a = np.radians(k * 18.0)
        rows.append(f"GOTO/{10 * np.cos(a):.4f},{10 * np.sin(a):.4f},5,"
                    f"{0.5 * np.cos(a):.6f},{0.5 * np.sin(a):.6f},{np.sqrt(0.75):.6f}")  # fmt: skip
    rows.append("END")
    cl.write_text("\n".join(rows) + "\n")
    out = tmp_path / "wind.h"
    urdf = tmp_path / "limited.urdf"
    text = Path(load_machine("dmu50").path).read_text()
    text = re.sub(r'(<joint name="C" type=)"continuous"', r'\1"revolute"', text)
    text = re.sub(
        r'(<joint name="C" type="revolute">.*?<limit )', r'\1lower="-6.2832" upper="6.2832" ',
        text, count=1, flags=re.S,
    )  # fmt: skip
    urdf.write_text(text)
    code = main(
        ["post", str(cl), "-m", str(urdf), "-o", str(out), "-q", "--view", str(tmp_path / "v.html")]
    )
    assert code == 0
    page = (tmp_path / "v.html").read_text()
    data = json.loads(_payload(page))
    if not any(m["kind"] == "rewind" for m in data["marks"]):
        assert "REWIND" not in out.read_text().upper()
        pytest.skip("the job needed no rewind on this machine")
    assert any(m["kind"] == "rewind" and m["t1"] >= m["t0"] for m in data["marks"])


def _payload(page: str) -> str:
    m = re.search(r'<script type="application/json" id="view-data">(.*?)</script>', page, re.S)
    assert m
    return m.group(1)


def test_page_is_self_contained(dome_posts: dict[str, Path]) -> None:
    data, _, _ = _data(dome_posts["tcp"], stock=STOCK, color="speed")
    page = view_html(data)
    assert "three.js authors" in page.lower() or "three.js" in page.lower()
    assert not re.search(r'(src|href)="(https?:)?//', page)  # nothing fetched from a network
    assert json.loads(_payload(page))["samples"] == data["samples"]
    assert data["color"]["by"] == "speed" and data["stock"]["kind"] == "mesh"


def test_cli_view_and_post_view(
    dome_posts: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "v.html"
    code = main(
        [
            "view",
            str(dome_posts["machine"]),
            "-m",
            "dmu50",
            "--cl",
            str(DOME),
            "-o",
            str(out),
            "--color",
            "deviation",
        ]
    )
    assert code == 0 and out.stat().st_size > 500_000
    assert "wrote" in capsys.readouterr().out
    # deviation colours need the CL data: a usage error, nothing written
    bad = tmp_path / "bad.html"
    assert (
        main(
            [
                "view",
                str(dome_posts["machine"]),
                "-m",
                "dmu50",
                "-o",
                str(bad),
                "--color",
                "deviation",
            ]
        )
        == 2
    )
    assert not bad.exists()
    assert "--cl" in capsys.readouterr().err
    # a missing program: its name, exit 1
    assert main(["view", str(tmp_path / "none.nc"), "-m", "dmu50", "-o", str(bad)]) == 1
    assert "none.nc" in capsys.readouterr().err and not bad.exists()
    # the view may not be the program: refused before any work
    prog = tmp_path / "p.h"
    assert main(["post", str(DOME), "-m", "dmu50", "-o", str(prog), "--view", str(prog), "-q"]) != 0
    assert not prog.exists()


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


def _browse(
    page: Path, fragment: str, tmp_path: Path, what: str
) -> subprocess.CompletedProcess[str]:
    browser = _chromium()
    if browser is None:
        if CI:
            pytest.fail("chromium is not installed (CI installs Debian's chromium package)")
        pytest.skip("chromium is not installed")
    args = [
        browser, "--headless=new", "--no-sandbox", "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader", "--window-size=1000,700", "--hide-scrollbars",
        f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=10000",
        what, f"{page.as_uri()}#{fragment}",
    ]  # fmt: skip
    return subprocess.run(args, capture_output=True, text=True, timeout=120, check=False)


@pytest.mark.slow
def test_page_draws_and_plays_in_chromium(dome_posts: dict[str, Path], tmp_path: Path) -> None:
    """The view of the README's dome job in a real browser: no JavaScript error, the machine
    drawn in the 3-D area, and two times give two different pictures."""
    from PIL import Image

    page = tmp_path / "dome.html"
    assert (
        main(
            [
                "view",
                str(dome_posts["tcp"]),
                "-m",
                "dmu50",
                "--cl",
                str(DOME),
                "--stock",
                str(STOCK),
                "-o",
                str(page),
            ]
        )
        == 0
    )
    dom = _browse(page, "t=4", tmp_path, "--dump-dom")
    status = re.search(r'<div id="status" data-state="(\w+)">([^<]*)</div>', dom.stdout)
    assert status, dom.stdout[-2000:] + dom.stderr[-2000:]
    assert status.group(1) == "ready", status.group(2)
    assert re.search(r'<pre id="errors"></pre>', dom.stdout)
    assert re.search(r'<div id="block">block \d+ of \d+ · NC line \d+</div>', dom.stdout)
    shots = []
    for k, fragment in enumerate(("t=4", "t=14")):
        png = tmp_path / f"shot{k}.png"
        _browse(page, fragment, tmp_path, f"--screenshot={png}")
        assert png.is_file()
        shots.append(np.asarray(Image.open(png).convert("RGB"), dtype=np.int16))
    background = np.array([0x1D, 0x20, 0x26])
    for shot in shots:
        scene = shot[:540]  # the 3-D area (the panel is the bottom 150 px)
        drawn = np.abs(scene - background).sum(axis=2) > 40
        assert drawn.mean() > 0.2, drawn.mean()  # the machine fills much of the view
        assert drawn[100:440, 200:800].mean() > 0.3  # and its middle
    changed = np.abs(shots[0][:540] - shots[1][:540]).sum(axis=2) > 30
    assert changed.mean() > 0.01, changed.mean()  # the machine moved between the two times


def _two_tools(tmp_path: Path) -> tuple[Path, Path, dict]:
    """The dome with its 6 mm ball, then its first passes with a 10 mm end mill as tool 5,
    posted on dmu50 (TCP, Heidenhain): the CL file, the program and its view data."""
    lines = DOME.read_text().splitlines()
    body = [x for x in lines if x not in ("FINI", "END", "GOHOME")]
    second = ["LOADTL/5", "CUTTER/10.0", "SPINDL/8000,CLW", *lines[8:60], "FINI"]
    cl = tmp_path / "two.apt"
    cl.write_text("\n".join([*body, *second]) + "\n")
    program_path = tmp_path / "two.h"
    assert main(["post", str(cl), "-m", "dmu50", "-o", str(program_path), "-q"]) == 0
    dialect = dialect_for(None, str(program_path))
    text = program_path.read_text()
    program = dialect.read(text, path=str(program_path))
    data = view_data(load_machine("dmu50"), program, text, dialect, cl=read_cl(str(cl)))
    return cl, program_path, data


def test_each_tool_is_drawn_at_its_own_size(tmp_path: Path) -> None:
    """A job of two tools: the tool drawn has the diameter of the cutter of the tool loaded at
    each sample, and a length of at least four diameters."""
    _, program_path, data = _two_tools(tmp_path)
    assert data["tool"]["diameter"] == 6.0
    sizes = _array(data["tool"]["sizes"], "<f4", (data["samples"], 2))
    diameters = sizes[:, 0]
    change = int(np.argmax(diameters == 10.0))
    assert change > 0 and (diameters[:change] == 6.0).all() and (diameters[change:] == 10.0).all()
    assert (sizes[:, 1] >= 4.0 * diameters).all()
    move = _array(data["move"], "<i4", (data["samples"],))
    changes = [
        k for k, line in enumerate(program_path.read_text().splitlines()) if "TOOL CALL 5" in line
    ]
    assert len(changes) == 1 and move[change] > move[change - 1]


@pytest.mark.slow
def test_the_page_shows_each_tool_at_its_size(tmp_path: Path) -> None:
    """The two-tool job's page in a real browser: the panel names the diameter of the tool
    drawn, 6 mm before the tool change and 10 mm after it."""
    cl, program_path, data = _two_tools(tmp_path)
    page = tmp_path / "two.html"
    assert main(["view", str(program_path), "-m", "dmu50", "--cl", str(cl), "-o", str(page)]) == 0
    t = _array(data["t"], "<f8", (data["samples"],))
    sizes = _array(data["tool"]["sizes"], "<f4", (data["samples"], 2))
    change = int(np.argmax(sizes[:, 0] == 10.0))
    for time, diameter in ((t[change // 2], "6.000"), ((t[change] + t[-1]) / 2, "10.000")):
        dom = _browse(page, f"t={time:.3f}", tmp_path, "--dump-dom").stdout
        assert re.search(r'<div id="status" data-state="ready">', dom), dom[-2000:]
        assert re.search(r'<pre id="errors"></pre>', dom)
        assert f'<span id="tool">tool \u00d8{diameter} mm</span>' in dom, re.findall(
            r'<span id="tool">[^<]*</span>', dom
        )
