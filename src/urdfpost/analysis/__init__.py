"""The lab tools: strategy comparison, metrics, plots and synthetic test paths.

Nothing in the core imports this package; :mod:`urdfpost.analysis.plot` needs matplotlib (the
``plot`` extra).
"""

COLOR_BY = ("deviation", "speed")
"""What the 3-D view (:func:`urdfpost.analysis.view.view_html`) may colour the tool-tip trace by
(here, so that the command line's options have it without the view's imports)."""
