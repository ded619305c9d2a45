"""Collision checks: bodies, pairs, single configurations, sampled moves, clearance, errors."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import trimesh

from urdfpost.collision import JOB_BODIES, CollisionWorld, ToolBody
from urdfpost.errors import GeometryError, UrdfpostError
from urdfpost.kinematics import inverse
from urdfpost.machine import Box, Machine, list_machines, load_machine, machine_from_urdf
from urdfpost.units import M_TO_MM

TOOL_LENGTH = 100.0  # mm; default tool: 10 mm cutter 20 mm long, 40 x 60 mm holder

# a 40 x 40 mm post on the dmu50 C table, 120 mm tall, from x = 100 to 140 mm in the workpiece
# frame (the workpiece frame is at (0.015, -0.01, 0.11) in the c_table frame)
POST = """
  <joint name="post_mount" type="fixed">
    <parent link="c_table"/><child link="post"/><origin xyz="0.135 -0.01 0.17"/>
  </joint>
  <link name="post">
    <collision name="post"><geometry><box size="0.04 0.04 0.12"/></geometry></collision>
  </link>
</robot>"""


@pytest.fixture
def logs(
    caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> pytest.LogCaptureFixture:
    """caplog that sees urdfpost's records even after the command line stopped propagation."""
    monkeypatch.setattr(logging.getLogger("urdfpost"), "propagate", True)
    caplog.set_level(logging.INFO, logger="urdfpost.collision")
    return caplog


@pytest.fixture(scope="module")
def dmu50() -> Machine:
    return load_machine("dmu50")


@pytest.fixture(scope="module")
def dmu50_post(dmu50: Machine) -> Machine:
    return machine_from_urdf(dmu50.urdf_text.replace("</robot>", POST), name="dmu50-post")


def q_at(
    machine: Machine, tip: tuple[float, ...], axis: tuple[float, ...] = (0, 0, 1)
) -> np.ndarray:
    """Joint vector putting the tool tip on ``tip`` along ``axis`` (first branch), shape (m,)."""
    axis_v = np.asarray(axis, dtype=float)
    ik = inverse(
        machine, np.array([tip], dtype=float), axis_v[None] / np.linalg.norm(axis_v), TOOL_LENGTH
    )
    assert ik.valid[0, 0]
    return ik.q[0, 0]


def box_stl(path: Path, lo: tuple[float, float, float], hi: tuple[float, float, float]) -> Path:
    lo_a, hi_a = np.array(lo, dtype=float), np.array(hi, dtype=float)
    mesh = trimesh.creation.box(extents=hi_a - lo_a)
    mesh.apply_translation((lo_a + hi_a) / 2)
    mesh.export(path)
    return path


# -- the tool -------------------------------------------------------------------------------


def test_tool_from_cutter_data() -> None:
    tool = ToolBody.from_cutter({"diameter": 8.0, "corner_radius": 4.0, "length": 50.0}, 120.0)
    assert tool.ball
    # a 50 mm tool 120 mm below the gauge point sits in a 70 mm holder (or extension)
    assert tool.holder_length == pytest.approx(70.0)
    assert tool.flute_length == pytest.approx(16.0)
    kinds = [(s.kind, s.z0, s.z1) for s in tool.sections(120.0)]
    assert kinds == [("cutter", -120.0, -104.0), ("shank", -104.0, -70.0), ("holder", -70.0, 0.0)]
    plain = ToolBody.from_cutter({"diameter": None, "corner_radius": None}, 100.0)
    assert plain == ToolBody()


def test_short_tool_shortens_the_holder_and_zero_length_has_no_tool() -> None:
    sections = ToolBody().sections(50.0)
    assert [(s.kind, s.z0, s.z1) for s in sections] == [
        ("cutter", -50.0, -30.0),
        ("holder", -30.0, 0.0),
    ]
    assert ToolBody().sections(0.0) == ()


@pytest.mark.parametrize(
    ("sizes", "message"),
    [
        ({"diameter": 0.0}, "diameter 0.0 mm: expected a positive length"),
        ({"diameter": 10.0, "corner_radius": 6.0}, "corner radius 6 mm is larger than half"),
        ({"holder_length": -5.0}, "holder length -5.0 mm"),
    ],
)
def test_nonsensical_tool_sizes(sizes: dict[str, float], message: str) -> None:
    with pytest.raises(GeometryError, match=message):
        ToolBody(**sizes)


# -- bodies and pairs -----------------------------------------------------------------------


def test_sides_and_pairs_from_the_tree(dmu50: Machine, tmp_path: Path) -> None:
    stock = box_stl(tmp_path / "part.stl", (-30, -30, 0), (30, 30, 30))
    world = CollisionWorld.build(dmu50, ToolBody(), TOOL_LENGTH, stock)
    side = {b.name: b.side for b in world.bodies}
    assert side["spindle_housing"] == side["column"] == side["holder"] == "head"
    assert side["c_table"] == side["cradle_floor"] == side["fixture_plate"] == "table"
    assert side["bed"] == side["trunnion_front"] == "static"
    assert side["stock"] == "table"
    pairs = set(world.checked_pairs())
    for pair in [
        ("holder", "stock"),
        ("shank", "stock"),
        ("spindle_housing", "stock"),
        ("cutter", "fixture_plate"),
        ("holder", "c_table"),
        ("head", "cradle_arm_front"),
        ("column", "bed"),
        ("stock", "cradle_arm_front"),  # the part on the C table against the B cradle
        ("stock", "bed"),
        ("c_table", "bed"),
    ]:
        assert pair in pairs, pair
    for pair in [
        ("cutter", "stock"),  # cutting
        ("holder", "spindle_housing"),  # same side
        ("stock", "fixture_plate"),  # rigidly together
        ("c_table", "cradle_floor"),  # same side
    ]:
        assert pair not in pairs and pair[::-1] not in pairs, pair


def test_shapes_touching_at_home_are_not_checked_and_said(logs: pytest.LogCaptureFixture) -> None:
    world = CollisionWorld.build(load_machine("monoblock"), ToolBody(), TOOL_LENGTH)
    assert ("c_table", "bed") in world.excluded
    assert ("c_table", "bed") not in world.checked_pairs()
    assert "c_table (c_table) and bed (base) touch at the home pose" in logs.text


@pytest.mark.parametrize("name", sorted(list_machines()))
@pytest.mark.parametrize("tool_length", [None, TOOL_LENGTH])
def test_home_pose_of_every_shipped_machine_is_clear(name: str, tool_length: float | None) -> None:
    machine = load_machine(name)
    world = CollisionWorld.build(machine, ToolBody(), tool_length)
    result = world.check(machine.home, clearance=True)
    assert not result.hit[0], result.pairs[0]
    assert result.clearance[0] > 0


# -- single configurations ------------------------------------------------------------------


def test_tool_plunged_into_the_table_collides(dmu50: Machine) -> None:
    world = CollisionWorld.build(dmu50, ToolBody(), TOOL_LENGTH)
    result = world.check(np.array([q_at(dmu50, (0, 0, -5)), q_at(dmu50, (0, 0, 5))]))
    assert result.hit.tolist() == [True, False]
    assert result.pairs == [("cutter", "fixture_plate"), None]


def test_cutting_the_stock_is_no_collision_but_the_holder_in_it_is(
    dmu50: Machine, tmp_path: Path
) -> None:
    # a wall from x = 10 to 60 mm, 60 mm high
    stock = box_stl(tmp_path / "wall.stl", (10, -30, 0), (60, 30, 60))
    world = CollisionWorld.build(dmu50, ToolBody(), TOOL_LENGTH, stock)
    cutting = q_at(dmu50, (12, 0, 50))  # cutter 7 mm into the wall, shank above it
    holder_in = q_at(dmu50, (0, 0, 10))  # cutter and shank clear, holder (r 20) in the wall
    above = q_at(dmu50, (0, 0, 70))
    result = world.check(np.array([cutting, holder_in, above]))
    assert result.hit.tolist() == [False, True, False]
    assert result.pairs[1] == ("holder", "stock")


def test_tall_fixture_hit_by_the_head_in_one_configuration_clear_in_another(
    dmu50_post: Machine,
) -> None:
    world = CollisionWorld.build(dmu50_post, ToolBody(), TOOL_LENGTH)
    s = np.sqrt(0.5)
    toward = q_at(dmu50_post, (0, 0, 20), (s, 0, s))  # spindle leans over the post
    away = q_at(dmu50_post, (0, 0, 20), (-s, 0, s))
    result = world.check(np.array([toward, away]))
    assert result.hit.tolist() == [True, False]
    assert result.pairs[0] == ("spindle_housing", "post")


def test_bad_joint_vectors_are_refused(dmu50: Machine) -> None:
    world = CollisionWorld.build(dmu50, ToolBody(), TOOL_LENGTH)
    with pytest.raises(ValueError, match=r"expected joint vectors of shape \(n, 5\)"):
        world.check(np.zeros((2, 4)))
    with pytest.raises(ValueError, match="NaN"):
        world.check(np.full(5, np.nan))


@pytest.mark.parametrize("ray_engine", [True, False])
def test_body_entirely_inside_a_closed_stock_collides(
    dmu50: Machine, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, ray_engine: bool
) -> None:
    if not ray_engine:  # neither embreex nor rtree: the winding-number fallback

        def no_ray_engine(*args: object) -> None:
            raise ImportError("no module named rtree")

        monkeypatch.setattr(trimesh.Trimesh, "contains", no_ray_engine)
    # the spindle shape starts 50 mm above the gauge point, so holder and shank can sit inside
    # the stock without any surface meeting another
    text = dmu50.urdf_text.replace(
        '<collision name="spindle_housing"><origin xyz="0 0 0.15"',
        '<collision name="spindle_housing"><origin xyz="0 0 0.2"',
    )
    machine = machine_from_urdf(text, name="dmu50-gap")
    q = q_at(machine, (0, 0, 10))  # tool from z = 10 to 110, spindle from 160
    closed = box_stl(tmp_path / "block.stl", (-60, -60, 0), (60, 60, 130))
    result = CollisionWorld.build(machine, ToolBody(), TOOL_LENGTH, closed).check(q)
    assert result.hit[0] and result.pairs[0][1] == "stock"
    assert result.pairs[0][0] in ("shank", "holder")
    assert (
        not CollisionWorld.build(machine, ToolBody(), TOOL_LENGTH, closed)
        .check(q_at(machine, (0, 0, 140)))
        .hit[0]
    )


# -- clearance ------------------------------------------------------------------------------


def test_clearance_is_positive_and_falls_as_the_tool_approaches(dmu50: Machine) -> None:
    world = CollisionWorld.build(dmu50, ToolBody(), TOOL_LENGTH)
    heights = [9.0, 6.0, 3.0, -1.0]
    result = world.check(np.array([q_at(dmu50, (0, 0, h)) for h in heights]), clearance=True)
    # the cutter's flat end above the fixture plate, nearer than the 10 mm gap between the
    # cradle arms and the trunnion
    assert result.clearance[:3] == pytest.approx(heights[:3], abs=1e-6)
    assert result.nearest[:3] == [("cutter", "fixture_plate")] * 3
    assert result.hit[3] and result.clearance[3] == 0.0
    far = world.check(q_at(dmu50, (0, 0, 50)), clearance=True)
    assert far.clearance[0] == pytest.approx(10.0, abs=1e-6)  # the machine's own gap
    job = world.check(q_at(dmu50, (0, 0, 50)), clearance=True, clearance_of=JOB_BODIES)
    assert job.clearance[0] == pytest.approx(50.0, abs=1e-6)
    assert job.nearest[0] == ("cutter", "fixture_plate")


def test_clearance_to_a_stock_mesh(dmu50: Machine, tmp_path: Path) -> None:
    stock = box_stl(tmp_path / "wall.stl", (30, -30, 0), (60, 30, 100))
    world = CollisionWorld.build(dmu50, ToolBody(diameter=10.0), TOOL_LENGTH, stock)
    xs = [-5.0, 0.0, 5.0]  # holder (r 20, from z = 70) gets 5 mm nearer the wall each time
    result = world.check(
        np.array([q_at(dmu50, (x, 0, 30)) for x in xs]), clearance=True, clearance_of=JOB_BODIES
    )
    assert not result.hit.any()
    # the holder's triangulated twin encloses the cylinder: at most 0.12 % of r nearer
    assert result.clearance == pytest.approx([15.0, 10.0, 5.0], abs=20 * 0.0013)
    assert result.nearest == [("holder", "stock")] * 3


def test_ball_end_cutter_ends_at_the_tip(dmu50: Machine) -> None:
    world = CollisionWorld.build(dmu50, ToolBody(diameter=10.0, corner_radius=5.0), TOOL_LENGTH)
    result = world.check(q_at(dmu50, (0, 0, 4)), clearance=True, clearance_of=JOB_BODIES)
    assert result.clearance[0] == pytest.approx(4.0, abs=1e-4)  # GJK on a capsule


# -- moves ----------------------------------------------------------------------------------


def test_move_between_clear_points_through_an_obstacle_is_caught(dmu50_post: Machine) -> None:
    world = CollisionWorld.build(dmu50_post, ToolBody(), TOOL_LENGTH)
    q = np.array([q_at(dmu50_post, (60, 0, 30)), q_at(dmu50_post, (180, 0, 30))])
    assert not world.check(q).hit.any()
    moves = world.check_moves(q, step_mm=1.0, step_deg=1.0)
    assert moves.hit.tolist() == [True]
    assert moves.pairs == [("holder", "post")]
    # the holder (r 20) reaches the post (x = 100) when the tip is at x = 80
    assert moves.at[0] == pytest.approx(20 / 120, abs=1.0 / moves.samples[0])
    assert moves.samples[0] == 120
    # one interval (ends only) misses it: the sampling is what finds it
    assert not world.check_moves(q, step_mm=1e6, step_deg=360.0).hit[0]
    over = np.array([q_at(dmu50_post, (60, 0, 130)), q_at(dmu50_post, (180, 0, 130))])
    assert not world.check_moves(over).hit[0]


def test_move_reports_a_colliding_end(dmu50: Machine) -> None:
    world = CollisionWorld.build(dmu50, ToolBody(), TOOL_LENGTH)
    q = np.array([q_at(dmu50, (0, 0, 10)), q_at(dmu50, (0, 0, 5)), q_at(dmu50, (0, 0, -5))])
    moves = world.check_moves(q)
    assert moves.hit.tolist() == [False, True]
    assert moves.pairs == [None, ("cutter", "fixture_plate")]
    assert 0.5 < moves.at[1] <= 0.6  # the tip passes z = 0 halfway


def test_sample_counts_follow_the_rule(dmu50: Machine) -> None:
    world = CollisionWorld.build(dmu50, ToolBody(), TOOL_LENGTH)
    home = dmu50.home
    lin = np.array([home, home + np.array([10.0, 0, 0, 0, 0])])
    assert world.sample_counts(lin, step_mm=1.0).tolist() == [10]
    turn = np.array([home, home + np.array([0, 0, 0, 0, np.radians(10.0)])])
    expected = np.ceil(world.levers["C"] * np.radians(10.0) / 2.0)
    assert world.sample_counts(turn, step_mm=2.0, step_deg=1.0).tolist() == [expected]
    assert world.sample_counts(turn, step_mm=1e6, step_deg=1.0).tolist() == [10]


def _world_points(world: CollisionWorld, machine: Machine, q: np.ndarray) -> np.ndarray:
    """Hull points of every body in the world frame, shape (n, points, 3), mm (from Pinocchio)."""
    model = machine.model
    data = model.createData()
    out = []
    for qi in q:
        pin.framesForwardKinematics(model, data, machine.pin_configuration(qi))
        pts = []
        for b in world.bodies:
            t = data.oMf[model.getFrameId(b.link, pin.FrameType.BODY)].homogeneous.copy()
            t[:3, 3] *= M_TO_MM
            t = t @ b.local
            pts.append(b.hull @ t[:3, :3].T + t[:3, 3])
        out.append(np.vstack(pts))
    return np.array(out)


@pytest.mark.parametrize("name", ["dmu50", "gantry-ca", "monoblock", "vf2-4axis"])
def test_no_body_point_moves_more_than_the_step_between_samples(name: str) -> None:
    machine = load_machine(name)
    world = CollisionWorld.build(machine, ToolBody(), TOOL_LENGTH)
    rng = np.random.default_rng(7)
    lo = np.where(np.isfinite(machine.lower), machine.lower, -np.pi)
    hi = np.where(np.isfinite(machine.upper), machine.upper, np.pi)
    step = 5.0
    for _ in range(3):
        q = lo + (hi - lo) * rng.uniform(0.45, 0.55, (2, len(machine.axes)))
        n = int(world.sample_counts(q, step_mm=step, step_deg=30.0)[0])
        fine = 4
        t = np.linspace(0.0, 1.0, n * fine + 1)
        pts = _world_points(world, machine, q[0] + t[:, None] * (q[1] - q[0]))
        steps = np.linalg.norm(np.diff(pts, axis=0), axis=2)  # (n * fine, points)
        # path length of every point over each sampled interval, pad of spheres aside
        per_interval = steps.reshape(n, fine, -1).sum(axis=1)
        assert per_interval.max() <= step + 1e-9


# -- files ----------------------------------------------------------------------------------


def test_missing_or_unreadable_stock_names_the_file(dmu50: Machine, tmp_path: Path) -> None:
    missing = tmp_path / "no_such_part.stl"
    with pytest.raises(GeometryError, match=r"no_such_part\.stl: stock file not found"):
        CollisionWorld.build(dmu50, ToolBody(), TOOL_LENGTH, missing)
    garbage = tmp_path / "garbage.stl"
    garbage.write_bytes(b"solid nothing\nendsolid nothing\n")
    with pytest.raises(UrdfpostError, match=r"garbage\.stl: (cannot read|the stock mesh has no)"):
        CollisionWorld.build(dmu50, ToolBody(), TOOL_LENGTH, garbage)


def test_open_stock_is_said(dmu50: Machine, tmp_path: Path, logs: pytest.LogCaptureFixture) -> None:
    mesh = trimesh.creation.box(extents=(20, 20, 20))
    mesh.update_faces(np.arange(len(mesh.faces) - 2))
    mesh.export(tmp_path / "open.stl")
    CollisionWorld.build(dmu50, ToolBody(), TOOL_LENGTH, tmp_path / "open.stl")
    assert "stock mesh is not closed" in logs.text


MESH_FIXTURE = """
  <joint name="block_mount" type="fixed">
    <parent link="c_table"/><child link="block"/><origin xyz="0.015 -0.01 0.11"/>
  </joint>
  <link name="block">
    <collision name="block"><geometry>
      <mesh filename="package://shop/meshes/{file}" scale="0.001 0.001 0.001"/>
    </geometry></collision>
  </link>
</robot>"""


def test_machine_shapes_are_data_in_mm(dmu50: Machine) -> None:
    shapes = {s.name: s for s in dmu50.shapes}
    plate = shapes["fixture_plate"]
    assert plate.link == "fixture"
    assert isinstance(plate.geometry, Box)
    assert plate.where.startswith(f"{dmu50.path}:") and "link 'fixture' <collision>" in plate.where
    world = CollisionWorld.build(dmu50, ToolBody(), TOOL_LENGTH)
    body = next(b for b in world.bodies if b.name == "fixture_plate")
    np.testing.assert_array_equal(body.local, plate.origin)
    assert body.hull.max(axis=0) == pytest.approx(plate.geometry.size / 2)
    assert len(dmu50.shapes) == sum(b.kind == "machine" for b in world.bodies)


AT_ODD = r"^odd\.urdf:\d+: link 'odd' <collision>: "


@pytest.mark.parametrize(
    ("element", "message"),
    [
        ("<capsule radius='0.01' length='0.1'/>", AT_ODD + "unknown shape <capsule>: expected box"),
        ("<box size='0.1 0.1'/>", AT_ODD + r"<box size>: '0\.1 0\.1': expected 3 numbers"),
        ("<sphere radius='0'/>", AT_ODD + "<sphere> has zero size"),
        ("<mesh filename='meshes/gone.stl'/>", r"^odd\.urdf: mesh 'meshes/gone\.stl' not found"),
    ],
)
def test_unreadable_collision_shape_is_said_when_checks_are_asked_for(
    dmu50: Machine, element: str, message: str
) -> None:
    text = dmu50.urdf_text.replace(
        "</robot>",
        f'<link name="odd"><collision><geometry>{element}</geometry></collision></link>'
        '<joint name="odd_mount" type="fixed"><parent link="c_table"/><child link="odd"/>'
        "</joint></robot>",
    )
    machine = machine_from_urdf(text, source="odd.urdf", name="dmu50-odd")  # still loads
    assert machine.family == dmu50.family
    with pytest.raises(GeometryError, match=message):
        machine.shapes  # noqa: B018
    with pytest.raises(GeometryError, match=message):
        CollisionWorld.build(machine, ToolBody(), TOOL_LENGTH)


def test_mesh_collision_geometry_from_a_package_path(dmu50: Machine, tmp_path: Path) -> None:
    (tmp_path / "shop" / "meshes").mkdir(parents=True)
    # a 40 mm cube (mesh in mm, scaled to metres) centred 100 mm along workpiece +X
    box_stl(tmp_path / "shop" / "meshes" / "block.stl", (80, -20, 0), (120, 20, 40))
    urdf_path = tmp_path / "shop" / "machine.urdf"
    urdf_path.write_text(dmu50.urdf_text.replace("</robot>", MESH_FIXTURE.format(file="block.stl")))
    machine = load_machine(urdf_path)
    world = CollisionWorld.build(machine, ToolBody(), TOOL_LENGTH)
    assert "block" in [b.name for b in world.bodies]
    result = world.check(
        np.array([q_at(machine, (100, 0, 35)), q_at(machine, (100, 0, 45))]), clearance=True
    )
    assert result.hit.tolist() == [True, False]
    assert result.pairs[0] == ("cutter", "block")
    assert result.clearance[1] == pytest.approx(5.0, abs=1e-3)

    urdf_path.write_text(dmu50.urdf_text.replace("</robot>", MESH_FIXTURE.format(file="gone.stl")))
    with pytest.raises(GeometryError, match=r"mesh 'package://shop/meshes/gone\.stl' not found"):
        CollisionWorld.build(load_machine(urdf_path), ToolBody(), TOOL_LENGTH)
