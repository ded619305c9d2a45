"""Plots of a strategy comparison: rotary angles and speeds against the CL index and against time.

matplotlib is imported when a plot is made (Agg canvas, no pyplot state), so posting never
needs it; it is the ``plot`` extra (``pip install 'urdfpost[plot]'``).
"""

from __future__ import annotations

import logging
import os
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from urdfpost._files import give_mode
from urdfpost.errors import UrdfpostError

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from urdfpost.analysis.compare import Comparison, Outcome

log = logging.getLogger(__name__)

__all__ = ["comparison_figure", "plot_comparison", "require_matplotlib"]

_LOG_RATIO = 30.0  # speed axis turns logarithmic when the peak exceeds the median this often
#: Label of the time axis: the timed trajectory (:mod:`urdfpost.analysis.timing`).
TIME_LABEL = "time from the first CL point (s, timed: axis velocity, acceleration limits)"
_TURN_LABEL = "turn in place: infinite speed demanded (colour of the strategy)"


def _cl_x(outcome: Outcome, s: np.ndarray, cl_s: np.ndarray) -> np.ndarray:
    """CL index of a strategy's rows: :attr:`Outcome.cl_index` (NaN for the moves the post
    adds before and after the CL points), else (no row reaches a CL point) the CL index at the
    same tip path position."""
    if outcome.cl_index is not None and len(outcome.cl_index) == len(s):
        return outcome.cl_index
    if len(cl_s) < 2:
        return np.zeros(len(s))
    return np.interp(s, cl_s, np.arange(len(cl_s), dtype=float))


def _time_x(t: np.ndarray, cl_x: np.ndarray) -> np.ndarray:
    """Time of a strategy's rows from its first CL point (NaN where ``cl_x`` is: the moves
    the post adds)."""
    on = np.flatnonzero(np.isfinite(cl_x))
    if on.size == 0:
        return t
    return np.where(np.isfinite(cl_x), t - t[on[0]], np.nan)


def _speed_scale(values: list[np.ndarray]) -> str:
    """ "log" when the positive speeds span more than :data:`_LOG_RATIO`, else "linear"."""
    pos = np.concatenate([v[np.isfinite(v) & (v > 0)] for v in values] or [np.zeros(0)])
    if pos.size == 0:
        return "linear"
    return "log" if pos.max() > _LOG_RATIO * np.median(pos) else "linear"


def require_matplotlib() -> None:
    """Check that matplotlib can be imported (before a long comparison whose plot it draws).

    Raises
    ------
    UrdfpostError
        When it cannot: the message says how to install it (the ``plot`` extra).
    """
    try:
        import matplotlib  # noqa: F401 (only its presence is checked here)
    except ImportError as e:  # the test extra installs matplotlib
        raise UrdfpostError("compare --plot needs matplotlib: pip install 'urdfpost[plot]'") from e


def plot_comparison(comparison: Comparison, path: Path | str, title: str = "") -> None:
    """Write the PNG of :func:`comparison_figure`.

    Parameters
    ----------
    comparison : Comparison
        Of :func:`urdfpost.analysis.compare.compare`.
    path : Path or str
        PNG file to write (replaced atomically).
    title : str
        Figure title.

    Raises
    ------
    UrdfpostError
        When matplotlib is not installed (the message says how to install it).
    """
    fig = comparison_figure(comparison, title)
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".png", dir=target.parent or ".")
    try:
        with os.fdopen(fd, "wb") as handle:
            fig.savefig(
                handle, format="png", dpi=110, metadata={"Software": None}, bbox_inches="tight"
            )
        give_mode(tmp, target)  # mkstemp makes it private; a plot is an ordinary file
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    log.debug("wrote %s", target)


def comparison_figure(comparison: Comparison, title: str = "") -> Figure:
    """A matplotlib figure (Agg canvas, no pyplot state) comparing the strategies.

    For each rotary axis of the machine, two rows of panels: the axis angle (degrees) and the
    speed the programmed feed demands of it (deg/s, without the velocity limit, so a strategy
    that asks for more than the machine can give shows above the dashed limit line; blocks that
    turn the axis without moving the tool tip, which demand an infinite speed, are marked by a
    triangle at the top of the panel). The left column is against the CL index (the CL points
    as read, 0 .. n - 1, fractional between them: :attr:`Outcome.cl_index`), with the singular
    spans shaded; the right one against the time on the timed trajectory (s: the axis velocity
    and acceleration limits and the feed, :mod:`urdfpost.analysis.timing`), its speed panels
    showing the axis speed on that trajectory.

    One line per strategy: solid when its program is verified, dashed and labelled "NOT
    verified: reason" when it misses its tolerance. A strategy that made no program has a
    hatched legend entry "failed: reason"; when none made one, the figure says so. Every line,
    marker and band has an entry in the legend below the panels.

    Parameters
    ----------
    comparison : Comparison
        Of :func:`urdfpost.analysis.compare.compare`.
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    UrdfpostError
        When matplotlib is not installed (the message says how to install it).
    """
    require_matplotlib()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    cl_s = np.asarray(comparison.cl_s, dtype=float)
    n_cl = len(cl_s)
    colours = {o.strategy: f"C{k % 10}" for k, o in enumerate(comparison.outcomes)}
    drawn = [o for o in comparison.outcomes if o.metrics and o.metrics.profile is not None]
    failed = [o for o in comparison.outcomes if o.metrics is None]
    profiles = [o.metrics.profile for o in drawn if o.metrics and o.metrics.profile is not None]
    rotary = profiles[0].rotary if profiles else ()
    timed = any(len(p.t) and np.isfinite(p.t[-1]) and p.t[-1] > 0 for p in profiles)
    rows, cols = max(2 * len(rotary), 1), 2 if timed else 1
    fig = Figure(figsize=(7.0 * cols, 2.6 * rows + 1.2 if rotary else 3.0), layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.subplots(rows, cols, sharex="col", squeeze=False)
    handles: dict[str, Any] = {}

    def keep(label: str, handle: Any) -> None:
        handles.setdefault(label, handle)

    for r, axis_name in enumerate(rotary):
        speeds: list[list[np.ndarray]] = [[] for _ in range(cols)]
        for c in range(cols):
            ax_q, ax_v = grid[2 * r, c], grid[2 * r + 1, c]
            for o in drawn:
                m = o.metrics
                assert m is not None and m.profile is not None
                prof = m.profile
                x = _cl_x(o, prof.s, cl_s)
                x = _time_x(prof.t, x) if c == 1 else x
                col = prof.column(axis_name)
                style = "-" if o.verified else "--"
                label = o.strategy if o.verified else f"{o.strategy}: NOT verified: {o.reason}"
                colour = colours[o.strategy]
                (line,) = ax_q.plot(x, prof.q[:, col], color=colour, lw=1.0, ls=style)
                keep(label, line)
                # left: what the feed demands over each block; right: the timed motion
                speed = np.abs(prof.demand[:, col] if c == 0 else prof.velocity[:, col])
                infinite = np.isinf(speed)
                speed = np.where(np.isfinite(speed), speed, np.nan)
                speeds[c].append(speed)
                draw = "steps-pre" if c == 0 else "default"
                ax_v.plot(x, speed, color=colour, lw=1.0, ls=style, drawstyle=draw)
                if infinite.any():
                    ax_v.plot(
                        x[infinite],
                        np.full(int(infinite.sum()), 0.97),
                        "v",
                        color=colour,
                        ms=5,
                        transform=ax_v.get_xaxis_transform(),
                    )
                    keep(
                        _TURN_LABEL,
                        Line2D([], [], color="0.3", marker="v", ls="none", ms=5),
                    )
            first = profiles[0]
            limit = float(first.limit[first.column(axis_name)])
            if np.isfinite(limit):
                label = f"{axis_name} velocity limit"
                keep(label, ax_v.axhline(limit, color="k", ls="--", lw=0.8))
            ax_q.set_ylabel(f"{axis_name} (deg)")
            what = "demanded at feed" if c == 0 else "timed"
            ax_v.set_ylabel(f"{axis_name} speed {what} (deg/s)")
        for c in range(cols):
            scale = _speed_scale(speeds[c])
            grid[2 * r + 1, c].set_yscale(scale)
            if scale == "log":  # a timed speed comes down to 0 at every stop: show 4 decades
                top = max(float(np.nanmax(v, initial=0.0)) for v in speeds[c])
                grid[2 * r + 1, c].set_ylim(bottom=top * 1e-4)
    if not rotary:  # no strategy made a program: say so where the curves would be
        for ax in grid.ravel():
            ax.set_yticks([])
        grid[0, 0].text(
            0.5,
            0.5,
            f"no strategy made a program ({len(failed)} failed: reasons in the legend)",
            ha="center",
            va="center",
            transform=grid[0, 0].transAxes,
        )
        grid[-1, 0].set_xlim(0, max(n_cl - 1, 1))
    for span in comparison.spans:
        label = f"singular span ({span.kind})"
        for ax in grid[:, 0]:
            band = ax.axvspan(span.first, span.last, color="0.6", alpha=0.25, lw=0)
        keep(label, band)
    for o in failed:
        colour = colours[o.strategy]
        patch = Patch(facecolor="none", edgecolor=colour, hatch="///")
        keep(f"{o.strategy}: failed: {o.reason}", patch)
    for ax in grid.ravel():
        ax.grid(True, lw=0.3, alpha=0.5)
    grid[-1, 0].set_xlabel(f"CL index (0 .. {max(n_cl - 1, 0)}, CL points as read)")
    if cols > 1:
        grid[-1, 1].set_xlabel(TIME_LABEL)
    if handles:
        fig.legend(
            list(handles.values()),
            list(handles.keys()),
            loc="outside lower center",
            ncols=2 if cols > 1 else 1,
            fontsize="small",
        )
    if title:
        fig.suptitle(title)
    return fig
