"""The tool tip path lengths of feed blocks (:func:`urdfpost.verification.feeds.tip_lengths`),
compiled.

Per block, in one loop: the forward kinematics at the block's samples by the code of the
verification's first pass (:func:`urdfpost.verification._deviation_kernel._sampled`, the tool
point carried through the chain's joints, the cosines and sines by angle addition along the
samples from those numpy worked out, :func:`_angles_along`), and the polyline of the tip through
them, summed in numpy's order. Nothing of size samples times blocks is made.

Imported by :data:`urdfpost.verification.feeds.KERNELS` when the tip lengths of a program
without TCP are first asked for on enough blocks; the machine code is cached on disk beside this
module (``__pycache__``). The numpy path stays the definition: the same operations in the same
order on the same cosines and sines, so the lengths are numpy's bit for bit
(``tests/test_feeds_kernel.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from urdfpost.verification._deviation_kernel import _angles_along, _kind, _sampled


@njit(cache=True, nogil=True, error_model="numpy")
def tip_lengths(
    joint_column: np.ndarray,
    joint_rotary: np.ndarray,
    joint_direction: np.ndarray,
    joint_pivot: np.ndarray,
    tool_point: np.ndarray,
    home_axis: np.ndarray,
    values: np.ndarray,
    start: np.ndarray,
    trig: np.ndarray,
    t: np.ndarray,
    length: np.ndarray,
) -> None:
    """The tool tip's path length through the samples of blocks of a program without TCP.

    Parameters
    ----------
    joint_column, joint_rotary, joint_direction, joint_pivot, tool_point, home_axis
        The chain (:class:`urdfpost.kinematics.forward.ChainArrays`), as
        :func:`urdfpost.verification._deviation_kernel.block_deviation` takes it.
    values : ndarray, shape (N, m)
        Program rows, mm / rad (machine axis values).
    start : ndarray, shape (n,), int64
        First row of each block (it runs to the next row).
    trig : ndarray, shape (k, 4, n)
        Per rotary joint and block, the cosine and sine of its angle at ``t[0]`` and of its
        change from one sample to the next (:func:`urdfpost.verification.feeds.block_trig`).
    t : ndarray, shape (s,)
        Evenly spaced sample parameters, ends included.

    Returns
    -------
    None
        Written: ``length`` (n,), mm, the length of the polyline of the tip through the
        samples of every block.
    """
    n, s = start.shape[0], t.shape[0]
    n_joints = joint_column.shape[0]
    kinds = np.empty(n_joints, dtype=np.int64)
    for j in range(n_joints):
        kinds[j] = _kind(joint_direction[j, 0], joint_direction[j, 1], joint_direction[j, 2])
    linear_columns = np.zeros(3, dtype=np.int64)  # (read in TCP programs only)
    cos_j = np.empty((n_joints, s))
    sin_j = np.empty((n_joints, s))
    qx, qy, qz = np.empty(s), np.empty(s), np.empty(s)
    vx, vy, vz = np.empty(s), np.empty(s), np.empty(s)
    for b in range(n):
        _angles_along(joint_rotary, trig, b, s, cos_j, sin_j)
        length[b] = _sampled(
            joint_column, joint_rotary, joint_direction, joint_pivot, kinds, linear_columns,
            tool_point, home_axis, values, start[b], t, s, cos_j, sin_j, False, 0.0, qx, qy,
            qz, vx, vy, vz,
        )  # fmt: skip
