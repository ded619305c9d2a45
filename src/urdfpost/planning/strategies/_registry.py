"""The registry the strategy modules fill, one ``@strategy`` decorator per strategy."""

from __future__ import annotations

from collections.abc import Callable

from urdfpost.planning.problem import Strategy

_REGISTERED: dict[str, tuple[int, Strategy]] = {}


def strategy(name: str, *, rank: int) -> Callable[[Strategy], Strategy]:
    """Register the decorated function as the strategy ``name``.

    Parameters
    ----------
    name : str
        What ``--strategy`` and the machine file call it.
    rank : int
        Its place in :data:`urdfpost.planning.strategies.STRATEGIES` (the order of the
        command line's help, of ``compare`` and of error messages): ascending, ties by name.

    Raises
    ------
    ValueError
        When ``name`` is registered already.
    """

    def register(fn: Strategy) -> Strategy:
        if name in _REGISTERED:
            other = _REGISTERED[name][1]
            raise ValueError(
                f"strategy {name!r} is registered twice: {other.__module__}.{other.__name__} "
                f"and {fn.__module__}.{fn.__name__}"
            )
        _REGISTERED[name] = (rank, fn)
        return fn

    return register


def registered() -> dict[str, Strategy]:
    """The registered strategies by name, in the order of their ranks (ties by name)."""
    order = sorted(_REGISTERED.items(), key=lambda item: (item[1][0], item[0]))
    return {name: fn for name, (_, fn) in order}
