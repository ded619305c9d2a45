"""Plots of a strategy comparison: rotary angles and speeds along the path, singular spans shaded.

matplotlib is imported when a plot is made (Agg canvas, no pyplot state), so posting never
needs it; it is the ``plot`` extra (``pip install 'urdfpost[plot]'``).
"""

from __future__ import annotations

import logging
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from urdfpost._files import give_mode
from urdfpost.analysis.metrics import Metrics
from urdfpost.errors import UrdfpostError
from urdfpost.planning.singularity import Span

log = logging.getLogger(__name__)

__all__ = ["plot_comparison"]

_LOG_RATIO = 30.0  # speed axis turns logarithmic when the peak exceeds the median this often


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


def plot_comparison(
    results: Sequence[tuple[str, Metrics]],
    spans: Sequence[Span],
    cl_s: np.ndarray,
    path: Path | str,
    title: str = "",
) -> None:
    """Write a PNG comparing strategies along the path.

    For each rotary axis of the machine, two panels against the path position s (mm): the
    axis angle (degrees) and the speed the programmed feed demands of it (deg/s, without the
    velocity limit, so a strategy that asks for more than the machine can give shows above the
    dashed limit line; blocks that turn the axis without moving the tool tip, which demand an
    infinite speed, are marked by a triangle at the top of the panel). One line per strategy;
    singular spans shaded.

    Parameters
    ----------
    results : sequence of (str, Metrics)
        Strategy name and its metrics; each must carry a :attr:`Metrics.profile`.
    spans : sequence of Span
        Singular spans of the CL data, drawn from ``cl_s[first]`` to ``cl_s[last]``.
    cl_s : ndarray, shape (n,), mm
        Path position of each CL point (:func:`urdfpost.analysis.metrics.cl_path_position`).
    path : Path or str
        PNG file to write (replaced atomically).
    title : str
        Figure title.

    Raises
    ------
    UrdfpostError
        When matplotlib is not installed (the message says how to install it).
    ValueError
        When there is nothing to plot, or a result carries no profile.
    """
    require_matplotlib()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if not results:
        raise ValueError("plot_comparison: expected at least one result, got none")
    for name, m in results:
        if m.profile is None:
            raise ValueError(f"plot_comparison: the metrics of {name!r} carry no profile")
    cl_s = np.asarray(cl_s, dtype=float)
    first = results[0][1].profile
    assert first is not None
    rotary = first.rotary
    fig = Figure(figsize=(10.0, 2.6 * 2 * max(len(rotary), 1) + 0.6), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2 * max(len(rotary), 1), 1, sharex=True, squeeze=False)[:, 0]
    colours = [f"C{k % 10}" for k in range(len(results))]
    for r, axis_name in enumerate(rotary):
        ax_q, ax_v = axes[2 * r], axes[2 * r + 1]
        speeds = []
        for (name, m), colour in zip(results, colours, strict=True):
            prof = m.profile
            assert prof is not None
            col = prof.column(axis_name)
            ax_q.plot(prof.s, prof.q[:, col], color=colour, lw=1.0, label=name)
            speed = np.abs(prof.demand[:, col])
            infinite = np.isinf(speed)
            speed = np.where(np.isfinite(speed), speed, np.nan)
            speeds.append(speed)
            ax_v.plot(prof.s, speed, color=colour, lw=1.0, drawstyle="steps-pre", label=name)
            if infinite.any():
                ax_v.plot(
                    prof.s[infinite],
                    np.full(int(infinite.sum()), 0.97),
                    "v",
                    color=colour,
                    ms=5,
                    transform=ax_v.get_xaxis_transform(),
                )
        limit = float(first.limit[first.column(axis_name)])
        if np.isfinite(limit):
            ax_v.axhline(limit, color="k", ls="--", lw=0.8, label=f"{axis_name} limit")
        ax_v.set_yscale(_speed_scale(speeds))
        ax_q.set_ylabel(f"{axis_name} (deg)")
        ax_v.set_ylabel(f"{axis_name} speed at feed (deg/s)")
        for ax in (ax_q, ax_v):
            ax.grid(True, lw=0.3, alpha=0.5)
    for k, span in enumerate(spans):
        lo, hi = cl_s[span.first], cl_s[span.last]
        for ax in axes:
            ax.axvspan(
                lo, hi, color="0.6", alpha=0.25, lw=0, label="singular span" if k == 0 else None
            )
    axes[0].legend(loc="best", fontsize="small")
    if len(axes) > 1:
        axes[1].legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("path position s (mm)")
    if title:
        fig.suptitle(title)

    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".png", dir=target.parent or ".")
    try:
        with os.fdopen(fd, "wb") as handle:
            fig.savefig(handle, format="png", dpi=110, metadata={"Software": None})
        give_mode(tmp, target)  # mkstemp makes it private; a plot is an ordinary file
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    log.debug("wrote %s", target)
