"""Axis acceleration and jerk limits in the machine file (``<urdfpost><axis_limits .../>``):
parsed in URDF units, checked at load with the file and line, given for every shipped axis."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from urdfpost.errors import MachineDefinitionError
from urdfpost.machine import list_machines, load_machine, machine_from_urdf
from urdfpost.machine.load import axis_limits


def with_limits(lines: str) -> str:
    """dmu50's file with its ``<axis_limits>`` elements replaced by ``lines``."""
    text = list_machines()["dmu50"].read_text(encoding="utf-8")
    text = re.sub(r"\s*<axis_limits [^>]*/>", "", text)
    return text.replace("</urdfpost>", f"{lines}\n  </urdfpost>", 1)


def line_of(text: str, needle: str) -> int:
    return next(i for i, t in enumerate(text.splitlines(), 1) if needle in t)


@pytest.mark.parametrize("name", sorted(list_machines()))
def test_every_shipped_axis_has_finite_limits(name: str) -> None:
    machine = load_machine(name)
    limits = axis_limits(machine)
    assert limits.axes == machine.axis_names
    for values in (limits.velocity, limits.acceleration, limits.jerk):
        assert np.all(np.isfinite(values) & (values > 0)), (name, values)
    # a jerk limit reached from rest within a second: jerk / acceleration >= 1/s
    assert np.all(limits.jerk >= limits.acceleration)


def test_urdf_units_become_mm_and_rad() -> None:
    text = with_limits(
        '    <axis_limits axis="X" acceleration="2.5" jerk="40"/>\n'
        '    <axis_limits axis="C" acceleration="12"/>'
    )
    limits = axis_limits(machine_from_urdf(text, "m.urdf", "m"))
    x, c, b = (limits.axes.index(a) for a in "XCB")
    assert limits.acceleration[x] == pytest.approx(2500.0) and limits.jerk[x] == 40000.0
    assert limits.acceleration[c] == 12.0 and math.isinf(limits.jerk[c])
    assert math.isinf(limits.acceleration[b])  # not given: no limit
    data = limits.as_dict(frozenset({"B", "C"}))
    assert data["C"]["acceleration"] == pytest.approx(math.degrees(12.0))
    assert data["X"]["velocity"] == pytest.approx(limits.velocity[x])


@pytest.mark.parametrize(
    ("element", "message"),
    [
        ('<axis_limits axis="W" acceleration="1"/>', r"axis='W'>: expected a moving joint"),
        ('<axis_limits axis="X" acceleration="0"/>', r"acceleration='0'>: expected a finite "),
        ('<axis_limits axis="X" jerk="-3"/>', r"jerk='-3'>: expected a finite number > 0"),
        ('<axis_limits axis="X" acceleration="nan"/>', r"expected a finite number > 0 \(m/s\^2"),
        ('<axis_limits axis="C" jerk="fast"/>', r"expected a finite number > 0 \(rad/s\^3"),
        ('<axis_limits axis="X" accel="1"/>', r"<axis_limits accel=...>: unknown attribute"),
    ],
)
def test_bad_limits_name_the_file_and_line(element: str, message: str) -> None:
    text = with_limits(f"    {element}")
    line = line_of(text, element)
    with pytest.raises(MachineDefinitionError, match=rf"^bad\.urdf:{line}: .*{message}"):
        machine_from_urdf(text, "bad.urdf", "bad")


def test_an_axis_given_twice_is_refused() -> None:
    text = with_limits(
        '    <axis_limits axis="X" acceleration="1"/>\n    <axis_limits axis="X" jerk="9"/>'
    )
    line = line_of(text, 'jerk="9"')
    with pytest.raises(MachineDefinitionError, match=rf"^bad\.urdf:{line}: .* given twice"):
        machine_from_urdf(text, "bad.urdf", "bad")
