"""Planning: from CL points to joint positions.

- :mod:`urdfpost.planning.branches`: the branch choice over the whole path (rules, costs, the
  min-plus engine);
- :mod:`urdfpost.planning.singularity`: conditioning of the orientation Jacobian and the
  singular spans of a path;
- :mod:`urdfpost.planning.strategies`: the singularity repair strategies, one registry, one
  signature.
"""
