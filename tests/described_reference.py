"""pinocchio's own evaluation of a described robot's closure layer: the reference the compiled
model (:mod:`ident_hw.model.tree_kernels`) is held to.

Everything here goes through pinocchio's algorithms on the robot's tree (``robot.model``), one
configuration at a time, as the project's first generic model did: frame placements and
Jacobians (``getFrameJacobian``, ``LOCAL_WORLD_ALIGNED``), classical frame accelerations
(``getFrameClassicalAcceleration``), the joint-torque regressor
(``computeJointTorqueRegressor``), the mass matrix (``crba``) and inverse dynamics (``rnea``); the
passive rates by a pseudo-inverse from an SVD. Nothing here calls the kernels.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin


def closure(robot, q) -> tuple[np.ndarray, np.ndarray]:
    """``(J (m, nv), r (m,))``: the closure Jacobian and residual at ``q`` (nq,)."""
    model, data = robot.model, robot.model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    J, r = [], []
    for c in robot.closures:
        a, b = data.oMf[c.frame1], data.oMf[c.frame2]
        d = (pin.getFrameJacobian(model, data, c.frame1, pin.LOCAL_WORLD_ALIGNED)
             - pin.getFrameJacobian(model, data, c.frame2, pin.LOCAL_WORLD_ALIGNED))
        J.append(d[:c.rows])
        r.append(a.translation - b.translation)
        if c.rigid:
            r.append(-a.rotation @ pin.log3(a.rotation.T @ b.rotation))
    if not J:
        return np.zeros((0, model.nv)), np.zeros(0)
    return np.vstack(J), np.concatenate(r)


def drift(robot, q, v) -> np.ndarray:
    """``gamma = Jdot v`` (m,) at ``q``, ``v``: the closure frames' relative classical acceleration."""
    model, data = robot.model, robot.model.createData()
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    out = []
    for c in robot.closures:
        a = (pin.getFrameClassicalAcceleration(model, data, c.frame1, pin.LOCAL_WORLD_ALIGNED)
             - pin.getFrameClassicalAcceleration(model, data, c.frame2, pin.LOCAL_WORLD_ALIGNED))
        out.append(a.vector if c.rigid else a.linear)
    return np.concatenate(out) if out else np.zeros(0)


def velocity_map(robot, q) -> tuple[np.ndarray, np.ndarray]:
    """``W`` (nv, n) with ``v = W Thetad`` and ``J_p^+`` (p, m) (SVD) at a closed ``q``."""
    act, pas = robot._act_v, robot._pas_v
    n = len(act)
    W = np.zeros((robot.model.nv, n))
    W[act, np.arange(n)] = 1.0
    if not robot.closures:
        return W, np.zeros((len(pas), 0))
    J, _ = closure(robot, q)
    pinv = np.linalg.pinv(J[:, pas], rcond=1e-10)
    W[pas] = -pinv @ J[:, act]
    return W, pinv


def motion(robot, q, Thetad, Thetadd) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(v, a, W)`` of the tree at a closed ``q`` for actuated rates and accelerations (n,)."""
    W, pinv = velocity_map(robot, q)
    v, a = W @ Thetad, W @ Thetadd
    if robot.closures:
        a[robot._pas_v] -= pinv @ drift(robot, q, v)
    return v, a, W


def regressor_rows(robot, q, Thetad, Thetadd) -> np.ndarray:
    """``W^T Y_tree(q, v, a)`` (n, 10 nb): the tree's part of the actuated regressor."""
    v, a, W = motion(robot, q, Thetad, Thetadd)
    return W.T @ pin.computeJointTorqueRegressor(robot.model, robot.model.createData(), q, v, a)


def plant_dynamics(robot, q, Thetad, params) -> tuple[np.ndarray, np.ndarray]:
    """``M = W^T M_tree W + diag(Jm)`` (n, n) and ``bias = W^T rnea(q, v, a0)`` (n,) at a closed
    ``q`` with the parameter vector ``params`` (bodies, then fv, fc, Jm)."""
    model = pin.Model(robot.model)
    model.armature[:] = 0.0
    for j in range(1, model.njoints):
        p = params[10 * (j - 1):10 * j]
        if p[0] != 0.0:
            model.inertias[j] = pin.Inertia.FromDynamicParameters(p)
        else:
            Ixx, Ixy, Iyy, Ixz, Iyz, Izz = p[4:10]
            model.inertias[j] = pin.Inertia(0.0, np.zeros(3), np.array([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz],
                                                                           [Ixz, Iyz, Izz]]))
    data = model.createData()
    n, b = len(robot._act_v), robot._n_body
    v, a0, W = motion(robot, q, Thetad, np.zeros(n))
    M_tree = pin.crba(model, data, q)
    M_tree = np.triu(M_tree) + np.triu(M_tree, 1).T
    M = W.T @ M_tree @ W + np.diag(params[b + 2 * n:b + 3 * n])
    return M, W.T @ pin.rnea(model, data, q, v, a0)
