"""The job setup: where the program zero sits on the machine (``Setup``, ``--setup``), and the
setup the travel error suggests."""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest
from urdfgen import rpy_matrix

from urdfpost.cli import main
from urdfpost.errors import MachineDefinitionError
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.kinematics.inverse import inverse
from urdfpost.machine import Setup, load_machine, machine_from_urdf, with_setup
from urdfpost.machine.load import resolve_machine
from urdfpost.machine.setup import matrix_from_rpy, rotation_about_z, rpy_from_matrix
from urdfpost.planning.setup_fit import fit_setup

ROOT = Path(__file__).resolve().parents[1]
DOME = ROOT / "examples" / "dome.apt"
MACHINES = ("dmu50", "dmu50-nutating", "gantry-ca", "monoblock", "umc750", "vf2-4axis", "xyzac-trt")
HINT = re.compile(r"--setup=(\S+) \(the program zero moved by")


def _random_q(machine, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(machine.lower), machine.lower, -np.pi)
    hi = np.where(np.isfinite(machine.upper), machine.upper, np.pi)
    return rng.uniform(lo, hi, size=(n, len(machine.axes)))


def _urdf(name: str) -> str:
    return resolve_machine(name).read_text(encoding="utf-8")


def _with_mount_rpy(text: str, rpy: str) -> str:
    """dmu50's text with another ``rpy`` on the workpiece joint."""
    old = '<origin xyz="0.015 -0.01 0.11" rpy="0 0 0"/>'
    assert text.count(old) == 1
    return text.replace(old, f'<origin xyz="0.015 -0.01 0.11" rpy="{rpy}"/>')


def _pin_placements(machine):
    """Pinocchio placements (world frame) of the workpiece and of its parent link at home."""
    import pinocchio as pin

    model = machine.model
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    pin.updateFramePlacements(model, data)
    work = data.oMf[model.getFrameId("workpiece")]
    parent = data.oMf[model.getFrameId(machine.mount.parent)]
    return work, parent


# -- the API -------------------------------------------------------------------------------


def test_the_default_is_the_urdf_placement() -> None:
    m = load_machine("dmu50")
    assert m.mount is not None
    assert m.mount.joint == "workpiece_mount" and m.mount.parent == "c_table"
    assert m.mount.setup == Setup() and m.mount.setup.is_default
    assert m.mount.origin == pytest.approx((15.0, -10.0, 110.0))
    assert m.mount.urdf_origin == m.mount.origin
    assert m.mount.rpy == (0.0, 0.0, 0.0)
    explicit = load_machine("dmu50", Setup())
    np.testing.assert_array_equal(explicit.home_tool_in_work, m.home_tool_in_work)


@pytest.mark.parametrize("name", MACHINES)
def test_every_shipped_machine_mounts_its_workpiece_on_a_fixed_joint(name: str) -> None:
    m = load_machine(name)
    assert m.mount is not None and m.mount.joint == "workpiece_mount"
    assert m.mount.rpy == (0.0, 0.0, 0.0)  # the docstring's statement about the shipped files


@pytest.mark.parametrize("name", ["dmu50", "gantry-ca", "vf2-4axis", "xyzac-trt"])
def test_an_offset_shifts_the_forward_kinematics_by_exactly_the_offset(name: str) -> None:
    base = load_machine(name)
    shift = np.array([12.5, -40.0, 7.25])  # mm, in the mount link's frame
    offset = tuple(np.array(base.mount.origin) + shift)
    moved = load_machine(name, Setup(offset))
    assert moved.mount.origin == pytest.approx(offset)
    assert moved.mount.setup.offset == pytest.approx(offset)
    q = _random_q(base, 50)
    tip0, axis0 = tip_and_axis(base, q, 30.0)
    tip1, axis1 = tip_and_axis(moved, q, 30.0)
    # the URDF's rpy is zero: the workpiece frame is the mount frame moved, so a point of the
    # machine is ``shift`` nearer to the new zero in every pose
    np.testing.assert_allclose(tip1, tip0 - shift, atol=1e-9)
    np.testing.assert_allclose(axis1, axis0, atol=1e-12)
    # Pinocchio's model follows: the workpiece frame moved by the shift along the mount frame
    (w0, parent), (w1, _) = _pin_placements(base), _pin_placements(moved)
    np.testing.assert_allclose(
        (w1.translation - w0.translation) * 1000.0, parent.rotation @ shift, atol=1e-9
    )
    np.testing.assert_allclose(w1.rotation, w0.rotation, atol=1e-15)
    # the axes' screws too: pivots move by -shift
    for a0, a1 in zip(base.rotary, moved.rotary, strict=True):
        np.testing.assert_allclose(a1.direction, a0.direction, atol=1e-12)
        np.testing.assert_allclose(
            np.cross(a1.direction, a1.pivot + shift - a0.pivot), 0.0, atol=1e-9
        )


def test_a_rotation_composes_with_the_urdf_rpy() -> None:
    rpy = np.array([0.3, -0.2, 0.5])
    text = _with_mount_rpy(_urdf("dmu50"), " ".join(repr(float(v)) for v in rpy))
    base = machine_from_urdf(text, "dmu50-rpy.urdf", "dmu50-rpy")
    turned = machine_from_urdf(text, "dmu50-rpy.urdf", "dmu50-rpy", Setup(rotation=30.0))
    c, s = np.cos(np.radians(30.0)), np.sin(np.radians(30.0))
    rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    expected = rz @ rpy_matrix(rpy)  # about the mount frame's Z, on top of the URDF's
    assert base.mount.rpy == pytest.approx(tuple(rpy))
    np.testing.assert_allclose(turned.mount.rotation, expected, atol=1e-12)
    assert turned.mount.origin == pytest.approx(base.mount.origin)  # the origin stays
    assert turned.mount.urdf_rpy == pytest.approx(tuple(rpy))
    (w0, parent), (w1, _) = _pin_placements(base), _pin_placements(turned)
    np.testing.assert_allclose(parent.rotation.T @ w1.rotation, expected, atol=1e-12)
    np.testing.assert_allclose(w1.translation, w0.translation, atol=1e-15)
    # a machine point in the new frame: p' = R'^T R p (same origin)
    q = _random_q(base, 40, seed=1)
    tip0, axis0 = tip_and_axis(base, q, 25.0)
    tip1, axis1 = tip_and_axis(turned, q, 25.0)
    turn = expected.T @ rpy_matrix(rpy)
    np.testing.assert_allclose(tip1, tip0 @ turn.T, atol=1e-9)
    np.testing.assert_allclose(axis1, axis0 @ turn.T, atol=1e-12)


def test_offset_and_rotation_together() -> None:
    base = load_machine("xyzac-trt")
    setup = Setup((30.0, 40.0, 60.0), -45.0)
    m = load_machine("xyzac-trt", setup)
    assert m.mount.setup == setup
    q = _random_q(base, 30, seed=2)
    tip0, _ = tip_and_axis(base, q)
    tip1, _ = tip_and_axis(m, q)
    # in the mount frame: p_mount = o + R p
    o0, o1 = np.array(base.mount.origin), np.array(m.mount.origin)
    np.testing.assert_allclose(tip0 + o0, tip1 @ rotation_about_z(-45.0).T + o1, atol=1e-9)


def test_with_setup_replaces_the_setup() -> None:
    m = load_machine("dmu50", Setup((0.0, 0.0, 50.0), 10.0))
    again = with_setup(m, Setup((1.0, 2.0, 3.0)))
    assert again.mount.setup == Setup((1.0, 2.0, 3.0))
    assert again.mount.rpy == (0.0, 0.0, 0.0)  # from the file's text, not on top of m's
    back = with_setup(m, None)
    np.testing.assert_allclose(back.home_tool_in_work, load_machine("dmu50").home_tool_in_work)


@pytest.mark.parametrize(
    "rpy",
    [
        (0.0, 0.0, 0.0),
        (0.3, -0.2, 0.5),
        (-3.0, 1.2, 2.9),
        (0.1, np.pi / 2, -0.4),  # gimbal lock: the matrix round trip still holds
        (0.7, -np.pi / 2 + 1e-9, 1.0),
        (np.pi, 0.0, -np.pi),
    ],
)
def test_rpy_round_trip(rpy: tuple[float, float, float]) -> None:
    r = rpy_matrix(np.array(rpy))
    np.testing.assert_allclose(matrix_from_rpy(np.array(rpy)), r, atol=1e-15)
    back = rpy_from_matrix(r)
    np.testing.assert_allclose(matrix_from_rpy(back), r, atol=1e-12)
    assert -np.pi / 2 <= back[1] <= np.pi / 2


def test_random_rotations_round_trip() -> None:
    rng = np.random.default_rng(3)
    for rpy in rng.uniform(-np.pi, np.pi, size=(200, 3)):
        r = rotation_about_z(rng.uniform(-180, 180)) @ rpy_matrix(rpy)
        np.testing.assert_allclose(matrix_from_rpy(rpy_from_matrix(r)), r, atol=1e-12)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("1,2,3", Setup((1.0, 2.0, 3.0))),
        (" -1.5, 2e1 ,3,90", Setup((-1.5, 20.0, 3.0), 90.0)),
    ],
)
def test_setup_parse(text: str, expected: Setup) -> None:
    assert Setup.parse(text) == expected


@pytest.mark.parametrize("text", ["", "1,2", "1,2,3,4,5", "a,b,c", "1,2,inf", "1,2,3,nan", "1;2;3"])
def test_setup_parse_refuses(text: str) -> None:
    with pytest.raises(ValueError, match=r"expected X,Y,Z or X,Y,Z,ROT"):
        Setup.parse(text)


def test_setup_refuses_what_is_not_finite() -> None:
    with pytest.raises(ValueError, match="3 finite numbers"):
        Setup((1.0, float("nan"), 0.0))
    with pytest.raises(ValueError, match="3 finite numbers"):
        Setup((1.0, 2.0))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="finite setup rotation"):
        Setup(rotation=float("inf"))
    scaled = Setup((1.0, 2.0, 3.0), 5.0).scaled(25.4)
    assert scaled.offset == pytest.approx((25.4, 50.8, 76.2)) and scaled.rotation == 5.0
    assert Setup(rotation=5.0).scaled(25.4) == Setup(rotation=5.0)


def _workpiece_as_root() -> str:
    """gantry-ca with the workpiece joint turned round: the workpiece is the root link."""
    text = _urdf("gantry-ca")
    old = '<parent link="base"/><child link="workpiece"/>'
    assert text.count(old) == 1
    return text.replace(old, '<parent link="workpiece"/><child link="base"/>')


def test_a_setup_needs_a_fixed_workpiece_joint() -> None:
    text = _workpiece_as_root()
    m = machine_from_urdf(text, "root.urdf", "root")  # loads without a setup
    assert m.mount is None
    with pytest.raises(MachineDefinitionError, match=r"root.urdf: cannot apply the job setup"):
        machine_from_urdf(text, "root.urdf", "root", Setup((0.0, 0.0, 10.0)))


# -- the setup the travel error suggests ---------------------------------------------------


def _apt(points: np.ndarray, axes: np.ndarray, units: str = "MM") -> str:
    lines = [f"UNITS/{units}", "MULTAX/ON", "LOADTL/1", "SPINDL/RPM,10000,CLW"]
    lines.append(f"FEDRAT/{'MMPM' if units == 'MM' else 'IPM'},500")
    for p, a in zip(points, axes, strict=True):
        lines.append("GOTO/" + ",".join(f"{v:.6f}" for v in (*p, *a)))
    lines.append("FINI")
    return "\n".join(lines) + "\n"


def _high_job(height: float, spread: float = 40.0, n: int = 25) -> tuple[np.ndarray, np.ndarray]:
    """A line of points ``height`` mm above the program zero, tool axis tilted 20 deg."""
    x = np.linspace(-spread / 2, spread / 2, n)
    points = np.stack([x, 0.2 * x, np.full(n, height)], axis=1)
    t = np.radians(20.0)
    axes = np.tile([np.sin(t), 0.0, np.cos(t)], (n, 1))
    return points, axes


def _post(tmp_path: Path, cl: Path, *args: str) -> int:
    return main(["post", str(cl), "-o", str(tmp_path / "part.nc"), "-q", *args])


def test_a_streamed_post_out_of_travel_says_where_the_setup_hint_is(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A streamed post never holds the whole CL data, which the setup hint needs: it says so
    and how to get one, writes nothing, and the whole post gives the hint."""
    points, axes = _high_job(700.0)
    cl = tmp_path / "high.apt"
    cl.write_text(_apt(points, axes), encoding="utf-8")
    assert _post(tmp_path, cl, "-m", "dmu50", "--piece-points", "10") == 1
    err = capsys.readouterr().err
    assert "outside the linear travel of machine dmu50" in err
    assert "a streamed post cannot suggest a job setup" in err and "--piece-points 0" in err
    assert not HINT.search(err)
    assert not (tmp_path / "part.nc").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["high.apt"]
    assert _post(tmp_path, cl, "-m", "dmu50", "--piece-points", "0") == 1
    assert HINT.search(capsys.readouterr().err)


def test_out_of_travel_job_posts_with_the_suggested_setup(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    points, axes = _high_job(700.0)  # dmu50's Z travel is 475 mm: 700 mm up is out of it
    cl = tmp_path / "high.apt"
    cl.write_text(_apt(points, axes), encoding="utf-8")
    assert _post(tmp_path, cl, "-m", "dmu50", "--no-tcp") == 1
    err = capsys.readouterr().err
    assert "outside the linear travel of machine dmu50" in err
    found = HINT.search(err)
    assert found, err
    assert "in the frame of c_table" in err and "would bring every CL point into travel" in err
    suggested = found.group(1)
    assert not (tmp_path / "part.nc").exists()
    assert _post(tmp_path, cl, "-m", "dmu50", "--no-tcp", f"--setup={suggested}") == 0
    out = capsys.readouterr().out
    assert "verification within tolerance" in out
    # the program is in machine coordinates: it verifies with the setup, not without it
    verify = ["verify", str(tmp_path / "part.nc"), "-m", "dmu50", "--cl", str(cl)]
    assert main([*verify, f"--setup={suggested}"]) == 0
    assert "within tolerance" in capsys.readouterr().out
    assert main(verify) == 1
    capsys.readouterr()


def test_the_shipped_dome_on_the_gantry(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the README's dome example, refused on gantry-ca with the URDF's zero (Z -952.785 mm)
    assert _post(tmp_path, DOME, "-m", "gantry-ca") == 1
    err = capsys.readouterr().err
    assert "Z would need -952.785 mm" in err
    found = HINT.search(err)
    assert found, err
    x, y, z = (float(v) for v in found.group(1).split(","))
    assert (x, y) == (215.0, -130.0)  # the URDF's X and Y: only Z had to change
    assert z > 100.0  # the zero higher up than the URDF's 100 mm
    assert _post(tmp_path, DOME, "-m", "gantry-ca", f"--setup={found.group(1)}") == 0
    assert "verification within tolerance" in capsys.readouterr().out


def test_the_suggestion_is_in_the_program_units(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    points, axes = _high_job(700.0)
    cl = tmp_path / "high.apt"
    cl.write_text(_apt(points, axes), encoding="utf-8")
    assert _post(tmp_path, cl, "-m", "dmu50", "--units", "inch") == 1
    err = capsys.readouterr().err
    found = HINT.search(err)
    assert found and " inch in the frame of c_table" in err, err
    mm = _post(tmp_path, cl, "-m", "dmu50")
    assert mm == 1
    found_mm = HINT.search(capsys.readouterr().err)
    assert found_mm
    inch = np.array([float(v) for v in found.group(1).split(",")])
    np.testing.assert_allclose(
        inch * 25.4, [float(v) for v in found_mm.group(1).split(",")], atol=0.02
    )
    assert _post(tmp_path, cl, "-m", "dmu50", "--units", "inch", f"--setup={found.group(1)}") == 0
    assert ", TCP, inch) for machine dmu50" in capsys.readouterr().out


def test_no_setup_brings_a_job_wider_than_the_travel_in(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    points, axes = _high_job(20.0, spread=2000.0)  # X travel of dmu50: 650 mm
    cl = tmp_path / "wide.apt"
    cl.write_text(_apt(points, axes), encoding="utf-8")
    assert _post(tmp_path, cl, "-m", "dmu50") == 1
    err = capsys.readouterr().err
    assert "outside the linear travel" in err
    assert "; no setup of the program zero brings every CL point into travel" in err
    assert "--setup=" not in err
    assert re.search(r"the nearest leaves a linear axis \d+\.\d{3} mm outside its travel", err)


def test_an_unreachable_orientation_gets_no_setup_hint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # tool pointing down on the umc750: beyond its B travel; no shift helps, none is offered
    cl = tmp_path / "down.apt"
    cl.write_text(_apt(np.array([[0, 0, 5.0], [0, 0, 0]]), np.array([[0, 0, 1.0], [0, 0, -1]])))
    assert _post(tmp_path, cl, "-m", "umc750") == 1
    err = capsys.readouterr().err
    assert "cannot be reached" in err and "setup" not in err


def test_the_fit_keeps_the_margin_and_is_the_smallest_shift() -> None:
    machine = load_machine("gantry-ca")  # head-head: the shift maps to the axes one to one
    points, axes = _high_job(-300.0)  # below the zero: Z travel runs out at the bottom
    fit = fit_setup(machine, points, axes, tool_length=150.0, margin=10.0)
    assert fit.needed and fit.shift is not None and fit.offset is not None
    assert fit.margin == pytest.approx(10.0)
    assert fit.shift[0] == 0.0 and fit.shift[1] == 0.0 and fit.shift[2] > 0.0
    moved = load_machine("gantry-ca", Setup(fit.offset))
    lo = np.array([a.lower for a in moved.linear])
    hi = np.array([a.upper for a in moved.linear])
    cols = list(moved.linear_columns)

    def room(m) -> np.ndarray:
        q = inverse(m, points, axes, 150.0).q[:, :, cols]  # (n, 2, 3)
        return np.nanmax(np.minimum(q - lo, hi - q).min(axis=2), axis=1)

    assert room(moved).min() == pytest.approx(10.0, abs=1e-6)
    less = load_machine("gantry-ca", Setup(tuple(np.array(fit.offset) - [0, 0, 0.01])))
    assert room(less).min() < 10.0  # any less shift leaves less margin
    assert fit_setup(moved, points, axes, tool_length=150.0).needed is False


def test_the_fit_is_fast_on_20000_points() -> None:
    machine = load_machine("dmu50")
    n = 20000
    t = np.linspace(0, 40 * np.pi, n)
    points = np.stack([80 * np.cos(t / 7), 60 * np.sin(t / 5), 650 + 10 * np.sin(t)], axis=1)
    tilt = np.radians(30 + 20 * np.sin(t / 3))
    axes = np.stack([np.sin(tilt) * np.cos(t), np.sin(tilt) * np.sin(t), np.cos(tilt)], axis=1)
    fit_setup(machine, points[:100], axes[:100], 100.0)  # (imports scipy)
    start = time.perf_counter()
    fit = fit_setup(machine, points, axes, 100.0)
    elapsed = time.perf_counter() - start
    assert fit.needed and fit.shift is not None
    assert elapsed < 1.0, elapsed


# -- the command line ----------------------------------------------------------------------


@pytest.mark.parametrize("value", ["1,2", "a,b,c", "1,2,3,4,5", "1,2,inf", "", "1,,3"])
@pytest.mark.parametrize("command", ["post", "verify", "compare"])
def test_bad_setup_values_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], value: str, command: str
) -> None:
    args = {
        "post": ["post", str(DOME), "-o", str(tmp_path / "x.nc")],
        "verify": ["verify", str(tmp_path / "x.nc"), "--cl", str(DOME)],
        "compare": ["compare", str(DOME)],
    }[command]
    with pytest.raises(SystemExit) as exc:
        main([*args, "-m", "dmu50", f"--setup={value}"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "argument --setup: expected X,Y,Z or X,Y,Z,ROT" in err
    assert not (tmp_path / "x.nc").exists()


def test_a_setup_the_machine_cannot_take_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    urdf = tmp_path / "root.urdf"
    urdf.write_text(_workpiece_as_root(), encoding="utf-8")
    rc = _post(tmp_path, DOME, "-m", str(urdf), "--setup=0,0,10")
    assert rc == 2
    assert "urdfpost: error: --setup:" in capsys.readouterr().err


def test_setup_help_says_what_the_numbers_mean(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["post", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--setup X,Y,Z[,ROT]" in text
    assert "program units" in text and "degrees about that link's +Z" in text


def test_compare_takes_the_setup(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["compare", str(DOME), "-m", "gantry-ca", "--strategies", "cone"])
    assert rc == 1  # the only strategy makes no program
    refused = capsys.readouterr().out
    assert "--setup=" in refused  # the outcome's error carries the hint
    rc = main(
        ["compare", str(DOME), "-m", "gantry-ca", "--strategies", "cone", "--setup=215,-130,122"]
    )
    assert rc == 0
    assert "--setup=" not in capsys.readouterr().out
