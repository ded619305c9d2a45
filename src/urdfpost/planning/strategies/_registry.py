"""The registry of strategies: the ``@strategy`` decorator and the plug-ins of other packages.

A strategy is registered in one of two ways:

- **In urdfpost or in a script**: decorate a function ``Problem -> Plan`` with
  ``@strategy("name", rank=N)``. The strategy modules of this package do so when the package
  is imported; a script's function counts from the moment its decorator runs.
- **In another package**: declare an entry point in the group :data:`ENTRY_POINT_GROUP`
  (``urdfpost.strategies``) whose name is the strategy's name and whose object is the
  function, e.g. in its ``pyproject.toml``::

      [project.entry-points."urdfpost.strategies"]
      hold = "urdfpost_hold:strategy_hold"

  The function's ``rank`` attribute, if it has one, is its rank; else :data:`PLUGIN_RANK`.

:data:`~urdfpost.planning.strategies.STRATEGIES` is a :class:`StrategyTable`, a live view of
the registry: the plug-ins are loaded the first time the strategies are listed (or a name is
looked up that urdfpost does not have), not when urdfpost is imported. A plug-in that cannot
be loaded is skipped with a warning naming its entry point; a plug-in whose name is taken
already is an error naming both.
"""

from __future__ import annotations

import importlib.metadata
import logging
from collections.abc import Callable, Iterator, MutableMapping
from typing import Any

from urdfpost.errors import UrdfpostError
from urdfpost.planning.problem import Strategy

log = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "urdfpost.strategies"
"""The entry-point group in which other packages declare strategies."""

PLUGIN_RANK = 1000
"""The rank of a plug-in (or a table entry) that names none: after every built-in strategy."""

_REGISTERED: dict[str, tuple[int, Strategy]] = {}
_ORIGIN: dict[str, str] = {}  # where each name was registered, for messages about clashes


def _qualified(fn: Any) -> str:
    """``module.name`` of a function, for messages."""
    return f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', repr(fn))}"


def _register(name: str, rank: int, fn: Strategy, origin: str) -> None:
    """Enter ``fn`` as ``name``; the same function under the same name again is no change.

    Raises
    ------
    UrdfpostError
        ``name`` is registered already for another function (the message names both).
    """
    if name in _REGISTERED:
        other = _REGISTERED[name][1]
        if other is fn:
            return
        raise UrdfpostError(f"strategy {name!r} is registered twice: {_ORIGIN[name]} and {origin}")
    _REGISTERED[name] = (rank, fn)
    _ORIGIN[name] = origin


def strategy(name: str, *, rank: int) -> Callable[[Strategy], Strategy]:
    """Register the decorated function as the strategy ``name``.

    Parameters
    ----------
    name : str
        What ``--strategy``, ``compare --strategies`` and the machine file call it.
    rank : int
        Its place in :data:`urdfpost.planning.strategies.STRATEGIES` (the order of the
        command line's help, of ``compare`` and of error messages): ascending, ties by name.

    Raises
    ------
    UrdfpostError
        When ``name`` is registered already for another function.

    Examples
    --------
    >>> from urdfpost.planning.strategies import STRATEGIES, exact_selection
    >>> from urdfpost.planning.strategies._common import _plain, _spans
    >>> @strategy("doc-exact", rank=900)
    ... def strategy_doc_exact(problem):
    ...     sel = exact_selection(problem, problem.toolpath)
    ...     return _plain(problem, problem.toolpath, sel, _spans(problem, problem.toolpath, sel))
    >>> "doc-exact" in STRATEGIES
    True
    >>> del STRATEGIES["doc-exact"]
    """

    def register(fn: Strategy) -> Strategy:
        _register(name, rank, fn, _qualified(fn))
        return fn

    return register


def registered() -> dict[str, Strategy]:
    """The registered strategies by name, in the order of their ranks (ties by name).

    Plug-ins are not loaded here (see :meth:`StrategyTable.load_plugins`).
    """
    order = sorted(_REGISTERED.items(), key=lambda item: (item[1][0], item[0]))
    return {name: fn for name, (_, fn) in order}


def _entry_point_text(ep: importlib.metadata.EntryPoint) -> str:
    """``name = value`` of an entry point, with its distribution when known."""
    dist = getattr(ep, "dist", None)
    where = f" (distribution {dist.name} {dist.version})" if dist is not None else ""
    return f"entry point {ep.name} = {ep.value}{where} in group {ep.group}"


def load_plugins(group: str = ENTRY_POINT_GROUP) -> list[str]:
    """Register the strategies other packages declare in the entry-point ``group``.

    Each entry point's name is the strategy's name and its object the function. One that
    cannot be imported, or whose object is not callable, is skipped with a warning naming the
    entry point and the reason.

    Parameters
    ----------
    group : str

    Returns
    -------
    list of str
        Names registered by this call.

    Raises
    ------
    UrdfpostError
        A plug-in's name is taken already by another strategy (built-in or plug-in); the
        message names both.
    """
    added: list[str] = []
    seen: set[tuple[str, str]] = set()
    for ep in sorted(importlib.metadata.entry_points(group=group), key=lambda e: e.name):
        if (ep.name, ep.value) in seen:  # one distribution found twice on sys.path
            continue
        seen.add((ep.name, ep.value))
        text = _entry_point_text(ep)
        if ep.name in _REGISTERED and _ORIGIN[ep.name] == text:
            continue
        try:
            fn = ep.load()
        except Exception as e:  # a plug-in can fail in any way: it must not stop the post
            log.warning(
                "strategy plug-in skipped: %s cannot be loaded: %s: %s", text, type(e).__name__, e
            )
            continue
        if not callable(fn):
            log.warning(
                "strategy plug-in skipped: %s is a %s, expected a function Problem -> Plan",
                text,
                type(fn).__name__,
            )
            continue
        rank = getattr(fn, "rank", PLUGIN_RANK)
        if not isinstance(rank, int) or isinstance(rank, bool):
            log.warning(
                "strategy plug-in %s: rank %r is not an integer; using %d", text, rank, PLUGIN_RANK
            )
            rank = PLUGIN_RANK
        if ep.name in _REGISTERED and _REGISTERED[ep.name][1] is not fn:
            raise UrdfpostError(
                f"strategy {ep.name!r} is registered twice: {_ORIGIN[ep.name]} and {text} "
                f"({_qualified(fn)})"
            )
        _register(ep.name, rank, fn, text)
        added.append(ep.name)
    if added:
        log.debug("strategy plug-ins: %s", ", ".join(added))
    return added


class StrategyTable(MutableMapping[str, Strategy]):
    """Every strategy by name, in the order of their ranks: a live view of the registry.

    Listing it (iterating, ``len``) loads the plug-ins of :data:`ENTRY_POINT_GROUP` once;
    looking up a built-in name does not, a name urdfpost does not have does. Setting an entry
    registers a strategy (rank :data:`PLUGIN_RANK` unless it replaces one), deleting one
    removes it: for scripts and tests.
    """

    def __init__(self, group: str = ENTRY_POINT_GROUP) -> None:
        self.group = group
        self._loaded = False

    def load_plugins(self) -> None:
        """Load the plug-ins of :attr:`group` (once; see :func:`load_plugins`)."""
        if not self._loaded:
            self._loaded = True  # a failure is reported once, not at every look-up
            load_plugins(self.group)

    def reload_plugins(self) -> None:
        """Look at the entry points again (after a package was installed while running)."""
        self._loaded = False
        self.load_plugins()

    def __getitem__(self, name: str) -> Strategy:
        if name not in _REGISTERED:
            self.load_plugins()
        return _REGISTERED[name][1]

    def __contains__(self, name: object) -> bool:
        if name in _REGISTERED:
            return True
        self.load_plugins()
        return name in _REGISTERED

    def __setitem__(self, name: str, fn: Strategy) -> None:
        rank = _REGISTERED[name][0] if name in _REGISTERED else PLUGIN_RANK
        _REGISTERED[name] = (rank, fn)
        _ORIGIN[name] = _qualified(fn)

    def __delitem__(self, name: str) -> None:
        del _REGISTERED[name]
        del _ORIGIN[name]

    def __iter__(self) -> Iterator[str]:
        self.load_plugins()
        return iter(registered())

    def __len__(self) -> int:
        self.load_plugins()
        return len(_REGISTERED)

    def __repr__(self) -> str:
        return f"StrategyTable({list(self)!r})"
