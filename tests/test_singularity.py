"""Singularity detector and repair strategies: closed-form facts and invariants."""

from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np
import pytest
from oracles import jacobian_pin

from urdfpost.analysis.compare import compare, table
from urdfpost.analysis.testpaths import great_circle_sweep, hemisphere_raster, nutating_edge
from urdfpost.errors import MachineDefinitionError
from urdfpost.kinematics.forward import tip_and_axis
from urdfpost.machine import load_machine, machine_from_urdf
from urdfpost.planning.problem import arc_length
from urdfpost.planning.singularity import conditioning, detect, orientation_jacobian
from urdfpost.planning.strategies import (
    DEFAULT_STRATEGY,
    STRATEGIES,
    Problem,
    exact_selection,
    split_at_pole_crossings,
)
from urdfpost.posting.check import check_piece
from urdfpost.posting.options import PostOptions, resolve
from urdfpost.posting.piece import post_piece
from urdfpost.posting.whole import post
from urdfpost.tolerances import Tolerances
from urdfpost.toolpath import Toolpath

MACHINES = ["dmu50", "gantry-ca", "monoblock", "dmu50-nutating", "xyzac-trt", "vf2-4axis"]
FAMILIES = {"dmu50": "table-table", "gantry-ca": "head-head", "monoblock": "head-table"}


def flat(tp: Toolpath) -> Toolpath:
    """The same path with a flat end mill: the cutting point is the tip."""
    events = tuple(
        replace(e, data={**e.data, "corner_radius": 0.0})
        if e.kind in ("cutter", "tool") and "diameter" in e.data
        else e
        for e in tp.events
    )
    return replace(tp, events=events)


def first_axis_travel_deg(result, m) -> float:
    from urdfpost.verification import program_joints

    q, _ = program_joints(m, result.program)
    # on the path: from the first CL point to the last (not the post's approach and end)
    on_cl = np.flatnonzero([mv.cl_line is not None for mv in result.program.moves()])
    q = q[on_cl[0] : on_cl[-1] + 1]
    col = m.axis_names.index(m.rotary[0].name)
    return float(np.degrees(np.abs(np.diff(q[:, col])).sum()))


# -- detector -----------------------------------------------------------------------------


@pytest.mark.parametrize("name", MACHINES)
def test_orientation_jacobian_matches_pinocchio(name: str) -> None:
    m = load_machine(name)
    rng = np.random.default_rng(7)
    q = rng.uniform(-1.0, 1.0, (25, len(m.axes)))
    _, v = tip_and_axis(m, q)
    omega = jacobian_pin(m, q)[:, 3:, :][:, :, list(m.rotary_columns)]
    expected = np.cross(omega.transpose(0, 2, 1), v[:, None, :]).transpose(0, 2, 1)
    assert np.abs(orientation_jacobian(m, q) - expected).max() < 1e-12


@pytest.mark.parametrize("name", MACHINES)
def test_conditioning_matches_the_singular_values(name: str) -> None:
    """The closed form for two rotary axes against numpy's SVD, near and far from poles."""
    m = load_machine(name)
    rng = np.random.default_rng(11)
    q = rng.uniform(-3.0, 3.0, (400, len(m.axes)))
    q[:100, m.rotary_columns[-1]] = rng.normal(0.0, 1e-6, 100)  # tilts near zero
    smin, kappa = conditioning(m, q)
    s = np.linalg.svd(orientation_jacobian(m, q), compute_uv=False)
    np.testing.assert_allclose(smin, s[:, -1], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(kappa[smin > 1e-9], (s[:, 0] / s[:, -1])[smin > 1e-9], rtol=1e-9)


def test_conditioning_is_sine_of_pole_distance_on_orthogonal_machines() -> None:
    """sigma = {1, sin(phi)} for an orthogonal machine, phi = angle to the first axis."""
    for name in ("dmu50", "gantry-ca", "monoblock"):
        m = load_machine(name)
        tilts = np.radians([0.5, 2.0, 10.0, 45.0, 90.0])
        q = np.zeros((len(tilts), len(m.axes)))
        q[:, m.rotary_columns[1]] = tilts
        q[:, m.rotary_columns[0]] = 0.7
        smin, kappa = conditioning(m, q)
        assert np.allclose(smin, np.sin(tilts), atol=1e-12)
        assert np.allclose(kappa, 1.0 / np.sin(tilts), rtol=1e-9)
    m = load_machine("dmu50")
    smin, kappa = conditioning(m, np.zeros(len(m.axes)))
    assert smin[0] < 1e-15 and np.isinf(kappa[0])


@pytest.mark.parametrize(("offset", "expect"), [(0.0, 1), (0.1, 1), (1.0, 1), (5.0, 0)])
def test_detector_finds_the_pole_spans(offset: float, expect: int) -> None:
    m = load_machine("gantry-ca")
    tp = great_circle_sweep(offset)
    problem = Problem(m, tp, tool_length=150.0, tol=Tolerances())
    base = split_at_pole_crossings(tp, m, problem.tol.pole_crossing)
    spans = detect(m, base, exact_selection(problem, base).q, problem.tol)
    assert len(spans) == expect
    for sp in spans:
        assert sp.kind == "pole"
        assert sp.min_sigma == pytest.approx(np.sin(np.radians(offset)), abs=1e-6)
        # the span covers the points within 2 degrees of the pole, and one more on each side
        # (a point 2 degrees from the pole to within rounding may count either way: the sweep
        # has points exactly there)
        tilt = np.degrees(np.arctan2(np.hypot(base.axis[:, 0], base.axis[:, 1]), base.axis[:, 2]))
        strict, loose = np.flatnonzero(tilt < 2.0 - 1e-9), np.flatnonzero(tilt < 2.0 + 1e-9)
        assert sp.first in (strict[0] - 1, loose[0] - 1)
        assert sp.last in (strict[-1] + 1, loose[-1] + 1)
        assert sp.first_line == base.line[sp.first]


def test_detector_finds_nothing_far_from_the_pole() -> None:
    """A path whose tool axis stays 20-60 degrees from the pole has no span on any machine."""
    n = 200
    t = np.linspace(0, 2 * np.pi, n)
    tilt = np.radians(40 + 20 * np.sin(3 * t))
    az = 0.3 * np.sin(t)
    axis = np.stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)], 1)
    tip = np.stack([30 * np.cos(t), 30 * np.sin(t), 150 + 5 * np.sin(t)], 1)
    tp = Toolpath.from_points(tip, axis, feed=1000.0, spindle=10000.0)
    for name in ("dmu50", "gantry-ca", "monoblock", "dmu50-nutating"):
        m = load_machine(name)
        problem = Problem(m, tp, tool_length=m.settings.tool_length, tol=Tolerances())
        spans = detect(m, tp, exact_selection(problem, tp).q, problem.tol)
        assert spans == [], name


def test_detector_finds_the_edge_of_a_nutating_machine() -> None:
    m = load_machine("dmu50-nutating")
    tp = nutating_edge()
    problem = Problem(m, tp, tool_length=m.settings.tool_length, tol=Tolerances())
    spans = detect(m, tp, exact_selection(problem, tp).q, problem.tol)
    assert [s.kind for s in spans] == ["edge"]
    edge = int(np.argmax(np.degrees(np.arccos(np.clip(tp.axis[:, 2], -1, 1)))))
    assert spans[0].first < edge < spans[0].last
    assert spans[0].min_sigma < 1e-6


# -- strategies -----------------------------------------------------------------------------


def test_registry_and_default() -> None:
    assert set(STRATEGIES) == {
        "none",
        "recursive",
        "branch-flip",
        "linear",
        "spline",
        "cone",
        "optimised",
    }
    assert DEFAULT_STRATEGY == "cone"


@pytest.mark.parametrize("name", sorted(STRATEGIES))
def test_strategies_never_mutate_their_input(name: str) -> None:
    m = load_machine("dmu50")
    tp = great_circle_sweep(0.1)
    before = copy.deepcopy(tp)
    problem = Problem(m, tp, tool_length=100.0, tol=Tolerances(), pivot=3.0, lift=0.5)
    arrays = {k: getattr(tp, k).copy() for k in ("tip", "axis", "feed", "motion", "line")}
    STRATEGIES[name](problem)
    for k, v in arrays.items():
        assert np.array_equal(getattr(tp, k), v, equal_nan=True), k
    assert tp.events == before.events


def test_great_circle_through_the_pole_branch_flip_keeps_c_still() -> None:
    """Exactly through the pole, with tilt travel on both sides: zero C motion."""
    m = load_machine("gantry-ca")  # A -110..110
    result = post(great_circle_sweep(0.0), m, PostOptions(strategy="branch-flip"))
    assert first_axis_travel_deg(result, m) < 1e-9
    # where the tilt cannot change sign (dmu50: B -5..110) C turns half a turn on the pole
    d = load_machine("dmu50")
    result = post(great_circle_sweep(0.0), d, PostOptions(strategy="branch-flip"))
    assert first_axis_travel_deg(result, d) == pytest.approx(180.0, abs=1e-6)


def test_branch_flip_bends_a_near_miss_through_the_pole() -> None:
    m = load_machine("gantry-ca")
    exact = post(great_circle_sweep(0.1), m, PostOptions(strategy="recursive"))
    flipped = post(great_circle_sweep(0.1), m, PostOptions(strategy="branch-flip"))
    assert first_axis_travel_deg(exact, m) > 170.0
    assert first_axis_travel_deg(flipped, m) < 10.0
    assert flipped.report.as_json()["strategy"]["bent"]
    assert flipped.verification.max_orientation_deviation_deg <= 0.1 + 0.5


def test_cone_keeps_c_within_its_velocity_limit_where_the_cone_allows() -> None:
    m = load_machine("gantry-ca")
    tp = flat(great_circle_sweep(0.1))
    res = compare(tp, m, ["recursive", "cone"])
    exact, cone = (o.metrics for o in res.outcomes)
    limit = exact.velocity_limit["C"]
    assert exact.peak_demand_velocity["C"] > 5 * limit
    assert cone.peak_demand_velocity["C"] <= limit * (1 + 1e-6)
    assert cone.max_orientation_deviation_deg <= 2.0 + 0.5
    assert cone.max_tip_deviation <= Tolerances().tip


def test_linear_runs_the_first_axis_linearly_across_the_span() -> None:
    m = load_machine("gantry-ca")
    tp = flat(great_circle_sweep(1.0))
    options = PostOptions(strategy="linear")
    plan = post_piece(tp, resolve(options, m, tp.units)).plan
    span = plan.spans[0]
    inside = (plan.param >= span.first) & (plan.param <= span.last)
    c = plan.rotary[inside, 0]
    # equally spaced CL points: constant C steps
    assert np.allclose(np.diff(c), np.diff(c)[0], atol=1e-9)
    assert abs(c[-1] - c[0]) > np.radians(100)


def test_spline_has_no_rate_step_at_the_span_ends() -> None:
    m = load_machine("gantry-ca")
    tp = flat(great_circle_sweep(1.0))
    plan = post_piece(tp, resolve(PostOptions(strategy="spline"), m, tp.units)).plan
    span = plan.spans[0]
    s = plan.param
    c = plan.rotary[:, 0]
    k = int(np.flatnonzero(s == span.first)[0])
    # rates per unit of path measure (the rows the spline inserts are points of its toolpath,
    # so a unit of position is a different length inside the span than outside)
    measure = arc_length(plan.toolpath)

    def along(x: np.ndarray) -> np.ndarray:
        return np.interp(x, np.arange(len(measure)), measure)

    outside = (c[k] - c[k - 1]) / (along(s[k : k + 1]) - along(s[k - 1 : k]))[0]
    h = 1e-6
    x = np.array([s[k], s[k] + h])
    inside = (plan.curve(x[1:])[0, 0] - c[k]) / float(np.diff(along(x))[0])
    # the curve leaves the entry at the rate of the block before it (equal CL steps)
    assert inside == pytest.approx(outside, rel=1e-3)
    # rows every 2 degrees of C at most
    steps = np.abs(np.diff(c[(s >= span.first) & (s <= span.last)]))
    assert steps.max() <= np.radians(2.0) + 1e-9


def test_spline_lift_is_counted_and_leaves_the_path_only_inside_the_span() -> None:
    m = load_machine("gantry-ca")
    tp = flat(great_circle_sweep(1.0))
    result = post(tp, m, PostOptions(strategy="spline", lift=1.0))
    assert result.report.as_json()["strategy"]["lifts"] == 1
    assert "lifted" in " ".join(result.verification.notes)


@pytest.mark.parametrize("name", sorted(STRATEGIES))
@pytest.mark.parametrize("machine_name", ["dmu50", "gantry-ca", "monoblock", "dmu50-nutating"])
@pytest.mark.parametrize("tcp", [True, False], ids=["tcp", "mc"])
def test_every_strategy_keeps_the_tool_tip_within_tolerance(
    name: str, machine_name: str, tcp: bool
) -> None:
    """On every family: the tip (flat tool) stays within tolerance of the CL path, also
    where the strategy bends the tool axis, and the program does what the strategy meant."""
    m = load_machine(machine_name)
    paths = (
        [nutating_edge()]
        if machine_name == "dmu50-nutating"
        else [great_circle_sweep(0.1), great_circle_sweep(1.0)]
    )
    tol = Tolerances()
    for tp in map(flat, paths):
        options = PostOptions(strategy=name, tcp=tcp)
        posted = post_piece(tp, resolve(options, m, tp.units))
        program = posted.program
        from urdfpost.dialects import dialect_for

        dialect = dialect_for(m.settings.controller)
        readback = dialect.read(dialect.write(program))
        cl, intended = check_piece(readback, m, posted.target, tol)
        assert cl.reached == len(tp)
        assert cl.max_tip_deviation <= tol.tip, (name, tp.source)
        if intended is not None:
            assert intended.ok, (name, tp.source, intended.summary())
            assert cl.max_orientation_deviation_deg <= 2.0 + 0.5
        elif name != "none":  # the naive baseline may miss the orientation at the pole
            assert cl.ok, (name, tp.source, cl.summary())


def test_ball_end_tool_pivots_about_the_ball_centre() -> None:
    """A bent axis keeps the ball centre on the CL centre path; the tip moves instead."""
    m = load_machine("gantry-ca")
    tp = great_circle_sweep(0.1)  # ball end, 3 mm radius
    result = post(tp, m, PostOptions(strategy="cone"))
    assert result.report.as_json()["strategy"]["pivot_mm"] == pytest.approx(3.0)
    check = result.verification
    assert check.ok
    tol = Tolerances()
    assert check.tip_tolerance == pytest.approx(tol.tip + 3.0 * tol.orientation)


def test_machine_file_names_the_default_strategy(tmp_path) -> None:
    text = load_machine("gantry-ca").urdf_text
    with_default = text.replace("<urdfpost ", '<urdfpost strategy="branch-flip" ', 1)
    m = machine_from_urdf(with_default, source="gantry.urdf", name="g")
    assert m.settings.strategy == "branch-flip"
    result = post(great_circle_sweep(0.1), m, PostOptions())
    assert result.report.as_json()["strategy"]["name"] == "branch-flip"
    # an unknown name is refused where the post's settings are resolved (the machine layer
    # knows no strategies), naming the machine file and the line of its <urdfpost> element
    bad = text.replace("<urdfpost ", '<urdfpost strategy="zigzag" ', 1)
    m = machine_from_urdf(bad, source="gantry.urdf", name="g")
    line = bad[: bad.index("<urdfpost ")].count("\n") + 1
    with pytest.raises(MachineDefinitionError, match=rf"^gantry.urdf:{line}: .*strategy=.zigzag.*"):
        post(great_circle_sweep(0.1), m, PostOptions())
    # a strategy named in the options wins over the machine file's
    assert post(great_circle_sweep(0.1), m, PostOptions(strategy="none")).report.strategy


def test_compare_table_lists_every_strategy() -> None:
    m = load_machine("dmu50")
    res = compare(great_circle_sweep(1.0), m, list(STRATEGIES))
    text = table(res)
    for name in STRATEGIES:
        assert name in text
    assert res.spans and res.spans[0].kind == "pole"
    data = res.as_dict()
    assert [s["strategy"] for s in data["strategies"]] == list(STRATEGIES)


def test_hemisphere_without_repair_c_rate_is_feed_over_offset() -> None:
    """Closed form: a pass at y0 from the apex of a hemisphere turns C at F / y0 (none)."""
    m = load_machine("gantry-ca")
    feed = 2000.0
    for y0 in (2.0, 5.0):
        tp = hemisphere_raster(offsets=(y0,), step=0.1, feed=feed)
        res = compare(tp, m, ["none"])
        demand = res.outcomes[0].metrics.peak_demand_velocity["C"]
        assert demand == pytest.approx(np.degrees(feed / 60.0 / y0), rel=0.01)
