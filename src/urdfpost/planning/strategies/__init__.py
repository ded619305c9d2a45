"""Singularity repair strategies: one registry, one signature, none mutates its input.

A strategy takes a :class:`~urdfpost.planning.problem.Problem` (the CL data, the machine and
the limits) and returns a :class:`~urdfpost.planning.problem.Plan` (rotary angles along the CL
path, optionally the joint curve between them); :mod:`urdfpost.planning.problem` states the
contract and :mod:`urdfpost.planning.realise` turns a plan into joint vectors. Each module of
this package describes its strategies; ``docs/singularity.md`` compares them and gives their
sources.

:data:`STRATEGIES` maps each name to its function, in the order of the strategies' ranks (the
order of the command line's help, of ``compare`` and of error messages);
:data:`DEFAULT_STRATEGY` is the one the pipeline takes when neither the options nor the
machine file name one.

Adding a strategy
-----------------
Add one module to this package; nothing else changes. Every module here whose name does not
start with ``_`` is imported with the package, and the ``@strategy`` decorator
(:func:`urdfpost.planning.strategies._registry.strategy`) registers its functions: the command
line, ``compare``, the machine file check and the tests over every strategy pick it up. For
example ``strategies/exact.py``::

    \"\"\"``exact``: exact inverse kinematics at the CL points, no pole crossings inserted.\"\"\"

    from urdfpost.planning.problem import Plan, Problem, exact_selection
    from urdfpost.planning.strategies._common import _plain, _spans
    from urdfpost.planning.strategies._registry import strategy


    @strategy("exact", rank=70)  # after cone (60) in STRATEGIES
    def strategy_exact(problem: Problem) -> Plan:
        \"\"\"Exact solutions, branches planned over the path, turns in place on the pole.\"\"\"
        tp = problem.toolpath
        sel = exact_selection(problem, tp)
        return _plain(problem, tp, sel, _spans(problem, tp, sel))

Shared pieces (pole crossings, turns in place, the closest tilt) are in ``_common``.
"""

from __future__ import annotations

from urdfpost._modules import public_modules
from urdfpost.planning.problem import (
    Plan,
    Problem,
    Strategy,
    arc_length,
    at_param,
    entry_mask,
    exact_selection,
    tool_axis_of,
)
from urdfpost.planning.realise import midpoint_solver, realise, solve_rows
from urdfpost.planning.strategies._common import best_tilt, split_at_pole_crossings
from urdfpost.planning.strategies._registry import registered, strategy

public_modules(__name__, __path__)  # each registers its strategies with @strategy

STRATEGIES: dict[str, Strategy] = registered()
"""Every strategy by name, in the order of their ranks."""

DEFAULT_STRATEGY = "cone"
"""The strategy taken when neither the options nor the machine file name one."""

__all__ = [
    "DEFAULT_STRATEGY",
    "STRATEGIES",
    "Plan",
    "Problem",
    "Strategy",
    "arc_length",
    "at_param",
    "best_tilt",
    "entry_mask",
    "exact_selection",
    "midpoint_solver",
    "realise",
    "solve_rows",
    "split_at_pole_crossings",
    "strategy",
    "tool_axis_of",
]
