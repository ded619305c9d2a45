"""Singular configurations: detection, repair strategies and their metrics.

- :mod:`urdfpost.singularity.detector`: conditioning of the orientation Jacobian and the
  singular spans of a path;
- :mod:`urdfpost.singularity.strategies`: the repair strategies, one registry, one signature;
- :mod:`urdfpost.singularity.metrics`: one set of figures for every strategy;
- :mod:`urdfpost.singularity.plot`: comparison plots.
"""

from urdfpost.singularity.detector import Span, conditioning, detect, orientation_jacobian

__all__ = ["Span", "conditioning", "detect", "orientation_jacobian"]
