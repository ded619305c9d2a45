"""Singularity repair strategies: one registry, one signature, none mutates its input.

A strategy takes a :class:`~urdfpost.planning.problem.Problem` (the CL data, the machine and
the limits) and returns a :class:`~urdfpost.planning.problem.Plan` (rotary angles along the CL
path, optionally the joint curve between them); :mod:`urdfpost.planning.problem` states the
contract and :mod:`urdfpost.planning.realise` turns a plan into joint vectors. Each module of
this package describes its strategies; ``docs/singularity.md`` compares them and gives their
sources.

:data:`STRATEGIES` maps each name to its function, in the order of the strategies' ranks (the
order of the command line's help, of ``compare`` and of error messages): a live view of the
registry (:class:`~urdfpost.planning.strategies._registry.StrategyTable`), so a strategy
registered by a script after import, or declared by another package in the entry-point group
``urdfpost.strategies`` (loaded when the strategies are first listed), is in it too;
:data:`DEFAULT_STRATEGY` is the one the pipeline takes when neither the options nor the
machine file name one. ``docs/strategies.md`` states the strategy API and the plug-in
mechanism.

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

Shared pieces (pole crossings, turns in place, the closest tilt) are in ``_common``. A strategy
in another package is a plug-in instead: see :mod:`urdfpost.planning.strategies._registry`
and ``examples/strategy_plugin``.
"""

from __future__ import annotations

import numpy as np

from urdfpost._modules import public_modules
from urdfpost.planning.branches import Selection
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
from urdfpost.planning.singularity import Span
from urdfpost.planning.strategies._common import (
    _plain,
    _turn_at_poles,
    best_tilt,
    split_at_pole_crossings,
)
from urdfpost.planning.strategies._registry import (
    ENTRY_POINT_GROUP,
    PLUGIN_RANK,
    StrategyTable,
    load_plugins,
    strategy,
)
from urdfpost.toolpath import Toolpath

public_modules(__name__, __path__)  # each registers its strategies with @strategy


def exact_rows(
    problem: Problem, toolpath: Toolpath, selection: Selection
) -> tuple[np.ndarray, np.ndarray]:
    """The rows of a selection's joint path: one per point of ``toolpath``, with the first
    rotary axis turned in place where the path leaves a pole (at points whose status is
    ``IKStatus.POLE``) and the arrival row before each rewind.

    Parameters
    ----------
    problem : Problem
    toolpath : Toolpath
        The CL data ``selection`` was made for.
    selection : Selection
        Its ``q`` (n, m) may be changed by the strategy (``dataclasses.replace``).

    Returns
    -------
    param : ndarray, shape (N,)
        Positions along ``toolpath`` (:attr:`Plan.param`).
    rotary : ndarray, shape (N, r), rad
    """
    return _turn_at_poles(problem.machine, selection, toolpath)


def exact_plan(
    problem: Problem, toolpath: Toolpath, selection: Selection, spans: list[Span]
) -> Plan:
    """The exact solutions of ``selection`` as a plan (:func:`exact_rows`, nothing bent, no
    curve): what a strategy returns where it changes nothing."""
    return _plain(problem, toolpath, selection, spans)


STRATEGIES: StrategyTable = StrategyTable()
"""Every strategy by name, in the order of their ranks (plug-ins loaded when first listed)."""

DEFAULT_STRATEGY = "cone"
"""The strategy taken when neither the options nor the machine file name one."""

__all__ = [
    "DEFAULT_STRATEGY",
    "ENTRY_POINT_GROUP",
    "PLUGIN_RANK",
    "STRATEGIES",
    "Plan",
    "Problem",
    "Strategy",
    "StrategyTable",
    "arc_length",
    "at_param",
    "best_tilt",
    "entry_mask",
    "exact_plan",
    "exact_rows",
    "exact_selection",
    "load_plugins",
    "midpoint_solver",
    "realise",
    "solve_rows",
    "split_at_pole_crossings",
    "strategy",
    "tool_axis_of",
]
