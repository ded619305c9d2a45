"""Planning: from CL points to joint positions.

- :mod:`urdfpost.planning.problem`: the contracts between the stages (``Problem``, ``Plan``,
  ``Strategy``) and the helpers that read the CL path;
- :mod:`urdfpost.planning.branches`: the branch choice over the whole path (rules, costs, the
  min-plus engine, collision exclusion, the search);
- :mod:`urdfpost.planning.rewinds`: what the machine does at a rewind (lift, turn, return);
- :mod:`urdfpost.planning.singularity`: conditioning of the orientation Jacobian and the
  singular spans of a path;
- :mod:`urdfpost.planning.strategies`: the singularity repair strategies, one registry, one
  signature, one module per family;
- :mod:`urdfpost.planning.realise`: joint vectors from a plan's rotary angles, and the
  midpoints of the generic subdivision.

Nothing here imports the pipeline (:mod:`urdfpost.posting`), the analysis or the command line.
"""
