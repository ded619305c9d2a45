"""Forward kinematics and Jacobians of the tool frame relative to the workpiece frame.

Two independent routes to the same numbers:

- :func:`tool_in_work` evaluates the product of exponentials derived at load time, vectorised
  over many joint vectors (used wherever the post needs speed: IK, subdivision, sampling);
- :func:`tool_in_work_pin` and :func:`jacobian_pin` ask Pinocchio, one configuration at a time
  (used to check every posted point and in tests).

Joint vectors ``q`` have shape (n, m): one column per machine axis in ``machine.axis_names``
order, mm for linear axes and rad for rotary axes. Positions are mm in the workpiece frame.
"""

from __future__ import annotations

import numpy as np

from urdfpost.machine import M_TO_MM, Machine


def skew(k: np.ndarray) -> np.ndarray:
    """Cross-product matrix of ``k``, shape (..., 3, 3) for ``k`` of shape (..., 3)."""
    k = np.asarray(k, dtype=float)
    z = np.zeros(k.shape[:-1])
    return np.stack(
        [
            np.stack([z, -k[..., 2], k[..., 1]], -1),
            np.stack([k[..., 2], z, -k[..., 0]], -1),
            np.stack([-k[..., 1], k[..., 0], z], -1),
        ],
        -2,
    )


def rotation_about(k: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Rodrigues rotation about unit axis ``k`` by angles ``theta``.

    Parameters
    ----------
    k : ndarray, shape (3,)
        Unit axis.
    theta : ndarray, shape (n,), rad

    Returns
    -------
    ndarray, shape (n, 3, 3)
    """
    theta = np.asarray(theta, dtype=float)
    kk = skew(k)
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    return np.eye(3) + s * kk + (1.0 - c) * (kk @ kk)


def rotate(k: np.ndarray, theta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` about unit axis ``k`` by ``theta`` (Rodrigues, vectorised).

    Parameters
    ----------
    k : ndarray, shape (3,) or (n, 3)
    theta : ndarray, shape (n,), rad
    v : ndarray, shape (3,) or (n, 3)

    Returns
    -------
    ndarray, shape (n, 3)
    """
    theta = np.asarray(theta, dtype=float)[..., None]
    k = np.broadcast_to(k, (*theta.shape[:-1], 3))
    v = np.broadcast_to(v, (*theta.shape[:-1], 3))
    kv = np.sum(k * v, axis=-1, keepdims=True)
    return v * np.cos(theta) + np.cross(k, v) * np.sin(theta) + k * kv * (1.0 - np.cos(theta))


def _as_q(machine: Machine, q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    q2 = q.reshape(-1, len(machine.axes))
    return q2


def tool_in_work(machine: Machine, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pose of the tool frame in the workpiece frame (product of exponentials, vectorised).

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m) or (m,)
        Joint values, mm / rad.

    Returns
    -------
    rotation : ndarray, shape (n, 3, 3)
    gauge : ndarray, shape (n, 3), mm
        Tool frame origin (gauge point) in the workpiece frame.
    """
    q = _as_q(machine, q)
    n = q.shape[0]
    rot = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    pos = np.zeros((n, 3))
    for a in sorted(machine.axes, key=lambda a: a.chain_index):
        col = q[:, machine.axis_names.index(a.name)]
        w, v = a.screw[:3], a.screw[3:]
        if a.rotary:
            r_j = rotation_about(w, col)
            # exp of a pure rotation about the line through cross(w, v): p = (I - R) c
            c = np.cross(w, v)
            p_j = c - r_j @ c
        else:
            r_j = None
            p_j = col[:, None] * v
        pos = pos + np.einsum("nij,nj->ni", rot, p_j)
        if r_j is not None:
            rot = rot @ r_j
    home = machine.home_tool_in_work
    gauge = pos + rot @ home[:3, 3]
    return rot @ home[:3, :3], gauge


def linear_directions(machine: Machine, q: np.ndarray) -> np.ndarray:
    """Derivative of the gauge point with respect to each linear axis (exact, vectorised).

    Each linear axis moves the tool, relative to the workpiece, along its direction rotated by
    the rotary joints that come before it in the chain from the workpiece.

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m), mm / rad

    Returns
    -------
    ndarray, shape (n, 3, 3)
        Column j is d(gauge)/d(linear axis j), linear axes in NC order (mm per mm).
    """
    q = _as_q(machine, q)
    n = q.shape[0]
    rot = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    cols: dict[str, np.ndarray] = {}
    for a in sorted(machine.axes, key=lambda a: a.chain_index):
        if a.rotary:
            rot = rot @ rotation_about(a.screw[:3], q[:, machine.axis_names.index(a.name)])
        else:
            cols[a.name] = rot @ a.screw[3:]
    return np.stack([cols[a.name] for a in machine.linear], axis=2)


def tip_and_axis(
    machine: Machine, q: np.ndarray, tool_length: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Tool tip and tool axis in the workpiece frame (vectorised).

    Parameters
    ----------
    machine : Machine
    q : ndarray, shape (n, m), mm / rad
    tool_length : float, mm
        Distance from the gauge point to the tool tip along the tool axis.

    Returns
    -------
    tip : ndarray, shape (n, 3), mm
    axis : ndarray, shape (n, 3)
        Unit tool axis (tool frame +Z).
    """
    rot, gauge = tool_in_work(machine, q)
    axis = rot[:, :, 2]
    return gauge - tool_length * axis, axis


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
    import pinocchio as pin

    q = _as_q(machine, q)
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
    """Tool tip (mm) and axis in the workpiece frame from Pinocchio; see :func:`tip_and_axis`."""
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
    import pinocchio as pin

    q = _as_q(machine, q)
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
