"""Choosing one joint solution per CL point.

The rules of Source A (``docs`` of the project: seeds.md), applied to the whole path at once:

- a candidate outside the travel of any axis (rotary or linear) is never taken; a point with no
  candidate left is an error naming its CL line;
- at the start (and after a tool change), the preferred branch is taken when it is within
  travel, unless keeping it would force a flip of branch later in the cut;
- a switch of branch between two regular points costs half a turn (it is a jump of the first
  rotary axis within one block); at a pole or edge the branches meet and switching is free;
- otherwise the choice follows the previous block: the total rotary motion along the path is
  minimised by dynamic programming (Viterbi) over every branch and every 360-degree multiple
  within travel, which is "nearest to the previous block" made global, so one block's greedy
  choice cannot lead the path into a travel limit that the other branch avoids;
- continuous axes take the 360-degree multiple nearest the previous block (the shortest rotation),
  so the steps to the previous and the next block are as small as they can be;
- at a pole (tool axis along the first rotary axis) that axis is undetermined and holds its
  previous value (its home value at the start).

The package, each module using only those above it:

- :mod:`.rules`: what a branch may be (candidates, travel, wrapping; :class:`Preference`,
  :class:`Selection`);
- :mod:`.costs`: the cost model (weights, the costs of the points);
- :mod:`.exclusion`: candidates and moves excluded because they collide;
- :mod:`.engine`: the min-plus (Viterbi) engine and the local planner;
- :mod:`.search`: :func:`select` and the search state it plans over.

What the machine does at a rewind is :mod:`urdfpost.planning.rewinds`.
"""

from urdfpost.planning.branches.costs import (
    JUMP,
    LIMIT_MARGIN,
    LIMIT_WEIGHT,
    REWIND_COST,
    TIME_WEIGHT,
)
from urdfpost.planning.branches.rules import TWO_PI, Preference, Selection
from urdfpost.planning.branches.search import select

__all__ = [
    "JUMP",
    "LIMIT_MARGIN",
    "LIMIT_WEIGHT",
    "REWIND_COST",
    "TIME_WEIGHT",
    "TWO_PI",
    "Preference",
    "Selection",
    "select",
]
