"""Reference implementations that the tests (and benchmarks) hold urdfpost to: Pinocchio's
forward kinematics and Jacobians, one configuration at a time.

They are not part of the package: urdfpost computes with the product-of-exponentials kernel of
:mod:`urdfpost.kinematics.forward`, and these are the independent route that checks it. Tests
import them as ``from oracles import tip_and_axis_pin`` (pytest puts ``tests/`` on
``sys.path``); a benchmark inserts the repository's ``tests`` directory into ``sys.path``
first.

Joint vectors ``q`` have shape (n, m) or (m,): one column per machine axis in
``machine.axis_names`` order, mm for linear axes and rad for rotary axes. Positions are mm in
the workpiece frame.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from urdfpost.kinematics.forward import skew
from urdfpost.machine import Machine
from urdfpost.units import M_TO_MM

__all__ = ["jacobian_pin", "tip_and_axis_pin", "tool_in_work_pin"]


def _as_q(machine: Machine, q: np.ndarray) -> np.ndarray:
    """``q`` as an (n, m) float array."""
    return np.asarray(q, dtype=float).reshape(-1, len(machine.axes))


def tool_in_work_pin(machine: Machine, q: np.ndarray) -> np.ndarray:
    """Pose of the tool frame in the workpiece frame, from Pinocchio.

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m) or (m,), mm / rad

    Returns
    -------
    ndarray, shape (n, 4, 4)
        Homogeneous transforms, translation in mm.
    """
    q = _as_q(machine, q)
    model: Any  # pinocchio.Model and pinocchio.Data (pinocchio is untyped)
    data: Any
    model, data = machine.model, machine._pin_data
    fw, ft = machine._frame_ids
    out = np.empty((q.shape[0], 4, 4))
    for i, qi in enumerate(q):
        pin.framesForwardKinematics(model, data, machine.pin_configuration(qi))
        out[i] = (data.oMf[fw].inverse() * data.oMf[ft]).homogeneous
    out[:, :3, 3] *= M_TO_MM
    return out


def tip_and_axis_pin(
    machine: Machine, q: np.ndarray, tool_length: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Tool tip (mm) and axis in the workpiece frame from Pinocchio; see
    :func:`urdfpost.kinematics.forward.tip_and_axis`."""
    t = tool_in_work_pin(machine, q)
    axis = t[:, :3, 2]
    return t[:, :3, 3] - tool_length * axis, axis


def jacobian_pin(machine: Machine, q: np.ndarray, tool_length: float = 0.0) -> np.ndarray:
    """Jacobian of the tool tip relative to the workpiece, in the workpiece frame, from Pinocchio.

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m) or (m,), mm / rad
    tool_length : float, mm
        The tip is this far from the gauge point along the tool axis.

    Returns
    -------
    ndarray, shape (n, 6, m)
        Rows 0-2: tip velocity (mm per mm, or mm per rad); rows 3-5: angular velocity of the tool
        relative to the workpiece (rad per mm, or rad per rad). Columns in ``axis_names`` order.
    """
    q = _as_q(machine, q)
    model: Any  # pinocchio.Model and pinocchio.Data (pinocchio is untyped)
    data: Any
    model, data = machine.model, machine._pin_data
    fw, ft = machine._frame_ids
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    cols = [model.joints[model.getJointId(a.name)].idx_v for a in machine.axes]
    scale = np.array([1.0 if a.rotary else 1.0 / M_TO_MM for a in machine.axes])
    out = np.empty((q.shape[0], 6, len(machine.axes)))
    for i, qi in enumerate(q):
        qp = machine.pin_configuration(qi)
        pin.computeJointJacobians(model, data, qp)
        pin.updateFramePlacements(model, data)
        j_t = pin.getFrameJacobian(model, data, ft, lwa)[:, cols]
        j_w = pin.getFrameJacobian(model, data, fw, lwa)[:, cols]
        o_m_w, o_m_t = data.oMf[fw], data.oMf[ft]
        r_w = o_m_w.rotation
        tip = o_m_t.translation - tool_length / M_TO_MM * o_m_t.rotation[:, 2]
        w_rel = j_t[3:] - j_w[3:]
        # tip velocity: frame origin velocity plus omega x (tip - origin); relative to the
        # workpiece frame, which moves with v_w + omega_w x (point - workpiece origin)
        v_tip = j_t[:3] + skew(tip - o_m_t.translation).T @ j_t[3:]
        v_work = j_w[:3] + skew(tip - o_m_w.translation).T @ j_w[3:]
        lin = r_w.T @ (v_tip - v_work) * M_TO_MM
        ang = r_w.T @ w_rel
        out[i] = np.vstack([lin, ang]) * scale
    return out
