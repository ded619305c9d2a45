"""Reports as strict JSON.

A report is plain data (dicts, lists, strings, numbers, booleans) that the post, ``verify`` and
``compare`` make. JSON has no infinity and no NaN, and strict parsers (``jq``, JavaScript's
``JSON.parse``, most databases) refuse the ``Infinity`` and ``NaN`` tokens that Python's
:func:`json.dumps` writes by default. So every non-finite figure is written as ``null``:

- an **infinite** figure means unbounded: ``max_kappa`` of a span whose orientation Jacobian is
  exactly singular (its smallest singular value is 0, so the condition number has no bound), an
  axis speed demanded by a block that turns an axis in no time;
- a **NaN** figure means undefined: a minimum or maximum over no values (a path with no
  feed moves has no largest feed-move deviation), a feed that the CL data never set.

The figure's name and the surrounding fields say which of the two applies; the documentation
of each report field (``docs/singularity.md`` for the strategy and metric figures) names the
ones that can be ``null``.

>>> report_json({"max_kappa": float("inf"), "spans": [1.5, float("nan")]})
'{\\n  "max_kappa": null,\\n  "spans": [\\n    1.5,\\n    null\\n  ]\\n}\\n'
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np


def json_ready(value: Any) -> Any:
    """``value`` as plain JSON data: numpy scalars as Python numbers, non-finite floats as None.

    Dicts (any mapping), lists and tuples are converted item by item; other values are returned
    as they are, so a value JSON cannot hold still fails in :func:`report_json`.
    """
    if isinstance(value, Mapping):
        return {k: json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def report_json(report: Mapping[str, Any]) -> str:
    """A report as strict JSON text (two-space indent, a final newline).

    Raises
    ------
    ValueError
        If a value is still non-finite after :func:`json_ready` (it cannot be: kept as a
        guard, ``allow_nan=False``).
    TypeError
        If a value is not plain data (an array, an object).
    """
    return json.dumps(json_ready(report), indent=2, allow_nan=False) + "\n"
