"""The lab tools: strategy comparison, metrics, plots and synthetic test paths.

Nothing in the core imports this package; :mod:`urdfpost.analysis.plot` needs matplotlib (the
``plot`` extra).
"""
