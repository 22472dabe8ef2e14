"""The described robot's tree and closure layer in compiled code: a model, a workspace, kernels.

pinocchio's model/data split is the example: :class:`CompiledTree` is the *model*, immutable
(made once from pinocchio's tree by :func:`tree_arrays`), and :class:`Workspace` the *data*,
the only thing a kernel writes besides its outputs: the closure state of the last sample solved
(its tree configuration ``q``, its velocity map ``W``, the factors of its closure Jacobian),
from which the next sample's Newton iterations start, and scratch. Two workspaces on one model
are two independent evaluations (the plant and the identification). Each is packed in two flat
arrays (integers, floats) that the kernels view as the named arrays of :class:`TreeArrays` and
:class:`TreeWorkspace`: numba takes a named tuple of arrays from Python array by array, about
0.4 µs each (20 µs a call for the two), two flat arrays at once.

The kernels (numba, compiled once and cached on disk) evaluate a batch of samples in one call,
with no Python per sample. They and their helpers are compiled without numba's reference counts
(``_nrt=False``): they allocate nothing (every array is the caller's or a view of the two flat
ones), and a helper that calls another otherwise updates the count of each of its array
arguments atomically on entry and on exit, about 400 such updates and 2 µs a Delta sample (a
quarter of its time, before this). Only the views' makers (``_take``, ``_tree``, ``_workspace``),
which Python calls too, keep them (``_nrt=True`` explicitly: a callee inherits its caller's
setting otherwise). A kernel that allocated would fail to compile, not run unsafely.

- the placements of every joint frame in the world (``oR`` (nj, 3, 3), ``op`` (nj, 3));
- the closure residuals ``r`` (m,) and their Jacobian ``J`` (m, nv), as
  :meth:`~ident_hw.model.described.DescribedRobot.closure_jacobian` defines them (pinocchio's
  ``getFrameJacobian`` in ``LOCAL_WORLD_ALIGNED``, frame 1 minus frame 2);
- Newton on the passive joints from the previous sample's state predicted to second order
  (``q_prev + W_prev d + q''/2``, ``d = Theta - Theta_prev``, ``q''_p = -J_p^+ gamma(W_prev d)``
  the loops' curvature along the step: one or two chord iterations at a 250 Hz sampling, one
  fewer than from the first order), Householder QR of ``J_p`` (square or with redundant rows alike);
- ``W`` (nv, n), the drift ``gamma``, ``a0``; the tree's accelerations with gravity as the base's
  acceleration ``-g``;
- the actuated regressor ``W^T Y_tree`` (n, 10 nb) without forming ``Y_tree`` (nv, 10 nb): each
  body's Newton-Euler wrench is linear in its ten parameters (pinocchio's order, about the joint
  frame's origin, in the joint frame), and the actuators see it through the body's actuated
  Jacobian ``J_i W`` (the virtual work ``tau = sum_i (J_i W)^T f_i``), built down the tree;
- the plant's ``M = sum_i (J_i W)^T I_i (J_i W)`` and bias ``sum_i (J_i W)^T f_i(v, a0, g)``.

Why numba and not code generated from the tree: the kernels are generic over the tree (its
topology is data, the arrays of :class:`TreeArrays`), compiled once for every description file
and cached, so a new file costs nothing at run time, and the code read and tested is the code
run; generated code would be a compiler per file, its output neither read nor cached across
files. Joints are one-degree-of-freedom (revolute or prismatic about any axis), so a
configuration is a vector with ``nq = nv = nj`` and joint ``j`` of pinocchio (``j >= 1``) is
index ``j - 1`` here. Everything is SI: rad, m, s, kg, N, N·m.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numba
import numpy as np

#: joint kinds in :attr:`TreeArrays.kind`
REVOLUTE_JOINT, PRISMATIC_JOINT = 0, 1
#: kernel status codes (:attr:`TreeWorkspace.status` [0]): solved; no assembly closes the loops
#: (Newton diverged or did not converge); the passive joints lose rank (Newton or ``W``)
OK, NO_ASSEMBLY, SINGULAR = 0, 1, 2
#: how far (rad, m, any coordinate) a guess may be from the last solved configuration for the
#: last velocity map to predict from it
PREDICT_RADIUS = 0.05


def _jit(nrt: bool = False, nogil: bool = False) -> Any:
    """numba's decorator as the kernels use it: compiled once and cached on disk; ``nrt`` False
    (the kernels and their helpers) without numba's reference counts (the module docstring);
    ``nogil``: releases the GIL (the kernels Python calls beside other threads)."""
    options: dict[str, Any] = {"_nrt": nrt}        # numba's option, not in its type stubs
    return numba.njit(cache=True, nogil=nogil, **options)


class TreeArrays(NamedTuple):
    """The tree and its closures as named arrays, views of a :class:`CompiledTree` (read-only).
    ``nj`` joints, ``n`` actuated, ``p`` passive, ``nc`` closures."""

    parent: np.ndarray      #: (nj,) int: parent joint index, -1 for the world
    kind: np.ndarray        #: (nj,) int: :data:`REVOLUTE_JOINT` or :data:`PRISMATIC_JOINT`
    axis: np.ndarray        #: (nj, 3): unit axis in the joint frame
    place_R: np.ndarray     #: (nj, 3, 3): rotation of the joint frame in its parent's at q = 0
    place_p: np.ndarray     #: (nj, 3): origin of the joint frame in its parent's (m)
    ancestor: np.ndarray    #: (nj, nj) int: ``ancestor[i, j]`` 1: joint j moves joint i's frame (j = i too)
    act: np.ndarray         #: (n,) int: the actuated joints, in actuator order
    pas: np.ndarray         #: (p,) int: the passive joints
    c_joint: np.ndarray     #: (nc, 2) int: the joints of each closure's two frames (-1: the world)
    c_R: np.ndarray         #: (nc, 2, 3, 3): each frame's rotation in its joint frame
    c_p: np.ndarray         #: (nc, 2, 3): each frame's origin in its joint frame (m)
    c_rigid: np.ndarray     #: (nc,) int: 1 for a weld (6 rows), 0 for a point joint (3 rows)
    c_row: np.ndarray       #: (nc + 1,) int: each closure's first row; the last is m
    gravity: np.ndarray     #: (3,): the gravity vector in the world (m/s²)
    home_q: np.ndarray      #: (nj,): the home configuration, the guess when there is no other
    tolerance: float        #: closure residual (m, rad) at which Newton stops
    singular: float         #: cond of ``J_p`` (1-norm of its R) beyond which a pose is singular
    plan: np.ndarray        #: int: how ``J_p`` is factored (:func:`elimination_plan`)


class TreeWorkspace(NamedTuple):
    """What a kernel writes besides its outputs, as named arrays, views of a :class:`Workspace`:
    the closure state of the last sample solved, and scratch. ``nj`` joints, ``n`` actuated,
    ``p`` passive, ``m`` rows."""

    last_q: np.ndarray      #: (nj,): the last configuration solved
    last_W: np.ndarray      #: (nj, n): its velocity map
    last_valid: np.ndarray  #: (1,) int: 1 where ``last_q``, ``last_W`` and ``QR`` hold a solved state
    QR: np.ndarray          #: (m, p): Householder QR of the last ``J_p`` (geqrf layout)
    tau: np.ndarray         #: (p,): its reflectors' factors
    status: np.ndarray      #: (2,) int: status code of the last call and the sample it refers to
    residual: np.ndarray    #: (1,): the largest residual where Newton failed
    oR: np.ndarray          #: (nj, 3, 3): joint frames' rotations in the world (scratch from here on)
    op: np.ndarray          #: (nj, 3): their origins (m)
    oa: np.ndarray          #: (nj, 3): the joints' axes in the world
    J: np.ndarray           #: (m, nj): the closure Jacobian
    r: np.ndarray           #: (m,): the closure residual
    b: np.ndarray           #: (m,): right-hand side
    x: np.ndarray           #: (p,): solution
    pp: np.ndarray          #: (p, p): R's inverse for its condition
    m3: np.ndarray          #: (3, 3, 3): rotations of a weld
    v3: np.ndarray          #: (3,)
    omega: np.ndarray       #: (nj, 3): angular velocities (world)
    dp: np.ndarray          #: (nj, 3): origin velocities
    alpha: np.ndarray       #: (nj, 3): angular accelerations
    ddp: np.ndarray         #: (nj, 3): origin accelerations
    wv: np.ndarray          #: (nj, 3, n): actuated Jacobians, world axes: linear
    ww: np.ndarray          #: (nj, 3, n): angular
    Jv: np.ndarray          #: (nj, 3, n): the same in each frame's axes: linear
    Jw: np.ndarray          #: (nj, 3, n): angular
    zero: np.ndarray        #: (nj,): zeros
    W1: np.ndarray          #: (nj, n): the plant's velocity map
    v1: np.ndarray          #: (nj,): the plant's rates
    a1: np.ndarray          #: (nj,): the plant's accelerations at zero actuated acceleration
    rows1: np.ndarray       #: (n, 10 nj): the plant's regressor rows
    F: np.ndarray           #: (6, n): the bodies' momenta per actuated rate


@dataclass(frozen=True)
class CompiledTree:
    """The compiled model of a described robot's tree and closures (immutable): two flat
    read-only arrays, ``ints`` (a header ``nj, n, p, nc, m``, then the integer arrays of
    :class:`TreeArrays`, the elimination plan last) and ``floats`` (its float arrays, then the tolerance and the singular
    condition), which :meth:`views` names."""

    ints: np.ndarray
    floats: np.ndarray

    def views(self) -> TreeArrays:
        """The named arrays (read-only views)."""
        return _tree(self.ints, self.floats)

    @property
    def act(self) -> np.ndarray:
        """The actuated joints' indices (n,)."""
        return self.views().act

    @property
    def pas(self) -> np.ndarray:
        """The passive joints' indices (p,)."""
        return self.views().pas

    @property
    def rows(self) -> int:
        """The closure rows ``m``."""
        return int(self.ints[4])


@dataclass(frozen=True)
class Workspace:
    """A compiled model's data: two flat arrays, ``floats`` and ``ints`` (``last_valid``, then
    the status code and sample of the last call), which :meth:`views` names."""

    floats: np.ndarray
    ints: np.ndarray

    def views(self, tree: CompiledTree) -> TreeWorkspace:
        """The named arrays (views: writing them writes the workspace)."""
        return _workspace(tree.ints, self.floats, self.ints)

    @property
    def last_valid(self) -> bool:
        """Whether it holds the closure state of a solved sample."""
        return bool(self.ints[0])

    @property
    def status(self) -> tuple[int, int]:
        """The last call's status code and the sample it refers to."""
        return int(self.ints[1]), int(self.ints[2])


def workspace(tree: CompiledTree) -> Workspace:
    """A fresh workspace for ``tree`` (no closure state yet)."""
    return Workspace(np.zeros(_workspace_size(tree.ints)), np.zeros(3, dtype=np.int64))


def _readonly(*arrays):
    for a in arrays:
        a.setflags(write=False)
    return arrays


def tree_arrays(model, closures, actuated_v, passive_v, home_q, tolerance: float, singular: float,
                kinds) -> CompiledTree:
    """The compiled model of pinocchio's ``model`` (one-degree-of-freedom joints only, their kinds
    ``kinds`` (nj,) of :data:`REVOLUTE_JOINT`, :data:`PRISMATIC_JOINT`), its ``closures``
    (``(frame1, frame2, rigid)`` frame ids of ``model``), the actuated and passive joints' indices
    in ``v``, the home configuration (nj,) and the Newton tolerance (m, rad) and singular
    condition. The gravity is ``model.gravity``."""
    nj = model.njoints - 1
    parent = np.array([model.parents[j] - 1 for j in range(1, model.njoints)], dtype=np.int64)
    kind = np.asarray(kinds, dtype=np.int64)
    axis, place_R, place_p = np.zeros((nj, 3)), np.zeros((nj, 3, 3)), np.zeros((nj, 3))
    for j in range(1, model.njoints):
        joint = model.joints[j]
        jdata = joint.createData()
        joint.calc(jdata, np.zeros(1))
        S = np.asarray(jdata.S).reshape(6)
        axis[j - 1] = S[3:] if kind[j - 1] == REVOLUTE_JOINT else S[:3]
        place_R[j - 1] = model.jointPlacements[j].rotation
        place_p[j - 1] = model.jointPlacements[j].translation
    ancestor = np.zeros((nj, nj), dtype=bool)
    for i in range(nj):
        j = i
        while j >= 0:
            ancestor[i, j] = True
            j = parent[j]
    nc = len(closures)
    c_joint = np.zeros((nc, 2), dtype=np.int64)
    c_R, c_p = np.zeros((nc, 2, 3, 3)), np.zeros((nc, 2, 3))
    c_rigid = np.zeros(nc, dtype=bool)
    c_row = np.zeros(nc + 1, dtype=np.int64)
    for c, (f1, f2, rigid) in enumerate(closures):
        for side, f in enumerate((f1, f2)):
            frame = model.frames[f]
            c_joint[c, side] = frame.parentJoint - 1
            c_R[c, side] = frame.placement.rotation
            c_p[c, side] = frame.placement.translation
        c_rigid[c] = rigid
        c_row[c + 1] = c_row[c] + (6 if rigid else 3)
    act, pas = np.array(actuated_v, dtype=np.int64), np.array(passive_v, dtype=np.int64)
    header = np.array([nj, len(act), len(pas), nc, c_row[-1]], dtype=np.int64)
    p = len(pas) if c_row[-1] else 0          # the passive columns of J_p (none without closures)
    structure = np.zeros((c_row[-1], p), dtype=bool)        # J_p's entries that can be non-zero
    for c in range(nc):
        for j in c_joint[c]:
            if j >= 0:
                structure[c_row[c]:c_row[c + 1]] |= ancestor[j, pas[:p]]
    ints = np.concatenate([header, parent, kind, act, pas, c_joint.ravel(), c_row, c_rigid.astype(np.int64),
                           ancestor.astype(np.int64).ravel(), elimination_plan(structure, c_row)])
    floats = np.concatenate([axis.ravel(), place_R.ravel(), place_p.ravel(), c_R.ravel(), c_p.ravel(),
                             np.array(model.gravity.linear, dtype=float), np.array(home_q, dtype=float),
                             [float(tolerance), float(singular)]])
    return CompiledTree(*_readonly(ints, floats))


# ---------------------------------------------------------------------------------- views
@_jit(nrt=True)
def _take(buf, offset, size):
    return buf[offset:offset + size], offset + size


@_jit(nrt=True)
def _tree(ti, tf):
    """The named arrays of a compiled tree's flat ``ints`` and ``floats`` (:class:`CompiledTree`)."""
    nj, n, p, nc = ti[0], ti[1], ti[2], ti[3]
    o = 5
    parent, o = _take(ti, o, nj)
    kind, o = _take(ti, o, nj)
    act, o = _take(ti, o, n)
    pas, o = _take(ti, o, p)
    c_joint, o = _take(ti, o, 2 * nc)
    c_row, o = _take(ti, o, nc + 1)
    c_rigid, o = _take(ti, o, nc)
    ancestor, o = _take(ti, o, nj * nj)
    plan = ti[o:]
    f = 0
    axis, f = _take(tf, f, 3 * nj)
    place_R, f = _take(tf, f, 9 * nj)
    place_p, f = _take(tf, f, 3 * nj)
    c_R, f = _take(tf, f, 18 * nc)
    c_p, f = _take(tf, f, 6 * nc)
    gravity, f = _take(tf, f, 3)
    home_q, f = _take(tf, f, nj)
    return TreeArrays(parent, kind, axis.reshape((nj, 3)), place_R.reshape((nj, 3, 3)), place_p.reshape((nj, 3)),
                      ancestor.reshape((nj, nj)), act, pas, c_joint.reshape((nc, 2)), c_R.reshape((nc, 2, 3, 3)),
                      c_p.reshape((nc, 2, 3)), c_rigid, c_row, gravity, home_q, tf[f], tf[f + 1], plan)


@_jit(nrt=True)
def _workspace_dims(ti):
    """``nj, n, p, m`` of a workspace (``p`` 0 where there is no closure)."""
    nj, n, m = ti[0], ti[1], ti[4]
    return nj, n, (ti[2] if m else 0), m


@_jit(nrt=True)
def _workspace_size(ti):
    nj, n, p, m = _workspace_dims(ti)
    return (nj + nj * n + m * p + p + 1 + 9 * nj + 3 * nj + 3 * nj + m * nj + 2 * m + p + p * p + 27 + 3
            + 12 * nj + 12 * nj * n + nj + nj * n + 2 * nj + 10 * nj * n + 6 * n)


@_jit(nrt=True)
def _workspace(ti, wf, wi):
    """The named arrays of a workspace's flat ``floats`` and ``ints`` (:class:`Workspace`)."""
    nj, n, p, m = _workspace_dims(ti)
    o = 0
    last_q, o = _take(wf, o, nj)
    last_W, o = _take(wf, o, nj * n)
    QR, o = _take(wf, o, m * p)
    tau, o = _take(wf, o, p)
    residual, o = _take(wf, o, 1)
    oR, o = _take(wf, o, 9 * nj)
    op, o = _take(wf, o, 3 * nj)
    oa, o = _take(wf, o, 3 * nj)
    J, o = _take(wf, o, m * nj)
    r, o = _take(wf, o, m)
    b, o = _take(wf, o, m)
    x, o = _take(wf, o, p)
    pp, o = _take(wf, o, p * p)
    m3, o = _take(wf, o, 27)
    v3, o = _take(wf, o, 3)
    omega, o = _take(wf, o, 3 * nj)
    dp, o = _take(wf, o, 3 * nj)
    alpha, o = _take(wf, o, 3 * nj)
    ddp, o = _take(wf, o, 3 * nj)
    wv, o = _take(wf, o, 3 * nj * n)
    ww, o = _take(wf, o, 3 * nj * n)
    Jv, o = _take(wf, o, 3 * nj * n)
    Jw, o = _take(wf, o, 3 * nj * n)
    zero, o = _take(wf, o, nj)
    W1, o = _take(wf, o, nj * n)
    v1, o = _take(wf, o, nj)
    a1, o = _take(wf, o, nj)
    rows1, o = _take(wf, o, 10 * nj * n)
    F, o = _take(wf, o, 6 * n)
    return TreeWorkspace(last_q, last_W.reshape((nj, n)), wi[0:1], QR.reshape((m, p)), tau, wi[1:3], residual,
                         oR.reshape((nj, 3, 3)), op.reshape((nj, 3)), oa.reshape((nj, 3)), J.reshape((m, nj)), r, b,
                         x, pp.reshape((p, p)), m3.reshape((3, 3, 3)), v3, omega.reshape((nj, 3)),
                         dp.reshape((nj, 3)), alpha.reshape((nj, 3)), ddp.reshape((nj, 3)), wv.reshape((nj, 3, n)),
                         ww.reshape((nj, 3, n)), Jv.reshape((nj, 3, n)), Jw.reshape((nj, 3, n)), zero,
                         W1.reshape((nj, n)), v1, a1, rows1.reshape((n, 10 * nj)), F.reshape((6, n)))


# ---------------------------------------------------------------------------------- small algebra
# The helpers take plain arrays, never the named tuples: numba passes a named tuple of arrays by
# value, its every array's reference counted, about 0.4 µs a call. 3-vectors are scalars: no
# heap array per product in the per-sample loops.
@_jit()
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@_jit()
def _log3(R, out):
    """The rotation vector (3,) of a rotation matrix (pinocchio's ``log3`` away from pi)."""
    c = min(1.0, max(-1.0, 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)))
    theta = np.arccos(c)
    k = 0.5 + theta * theta / 12.0 if theta < 1e-4 else 0.5 * theta / np.sin(theta)
    out[0] = k * (R[2, 1] - R[1, 2])
    out[1] = k * (R[0, 2] - R[2, 0])
    out[2] = k * (R[1, 0] - R[0, 1])


@_jit()
def _copy(src, dst):
    """``dst[:] = src`` (1-D, same length) as a loop: numba's slice assignment may allocate a
    temporary (it guards against overlap), which a kernel compiled without NRT cannot."""
    for i in range(src.shape[0]):
        dst[i] = src[i]


@_jit()
def _max_abs(x):
    out = 0.0
    for v in x:
        out = max(out, abs(v))
    return out


# ---------------------------------------------------------------------------------- kinematics
@_jit()
def _placements(parent, kind, axis, place_R, place_p, q, oR, op, oa):
    """The world rotation ``oR`` (nj, 3, 3), origin ``op`` (nj, 3) and axis ``oa`` (nj, 3) of
    every joint frame at ``q`` (nj,) (pinocchio's ``oMi``)."""
    for i in range(parent.shape[0]):
        P = place_R[i]
        ux, uy, uz = axis[i, 0], axis[i, 1], axis[i, 2]
        if kind[i] == REVOLUTE_JOINT:
            s, c = np.sin(q[i]), np.cos(q[i])
            t = 1.0 - c       # Rodrigues: Rj = c I + s [u]x + (1 - c) u u^T; the local rotation P Rj
            r00, r01, r02 = c + t * ux * ux, t * ux * uy - s * uz, t * ux * uz + s * uy
            r10, r11, r12 = t * uy * ux + s * uz, c + t * uy * uy, t * uy * uz - s * ux
            r20, r21, r22 = t * uz * ux - s * uy, t * uz * uy + s * ux, c + t * uz * uz
            l00 = P[0, 0] * r00 + P[0, 1] * r10 + P[0, 2] * r20
            l01 = P[0, 0] * r01 + P[0, 1] * r11 + P[0, 2] * r21
            l02 = P[0, 0] * r02 + P[0, 1] * r12 + P[0, 2] * r22
            l10 = P[1, 0] * r00 + P[1, 1] * r10 + P[1, 2] * r20
            l11 = P[1, 0] * r01 + P[1, 1] * r11 + P[1, 2] * r21
            l12 = P[1, 0] * r02 + P[1, 1] * r12 + P[1, 2] * r22
            l20 = P[2, 0] * r00 + P[2, 1] * r10 + P[2, 2] * r20
            l21 = P[2, 0] * r01 + P[2, 1] * r11 + P[2, 2] * r21
            l22 = P[2, 0] * r02 + P[2, 1] * r12 + P[2, 2] * r22
            px, py, pz = place_p[i, 0], place_p[i, 1], place_p[i, 2]
        else:
            l00, l01, l02 = P[0, 0], P[0, 1], P[0, 2]
            l10, l11, l12 = P[1, 0], P[1, 1], P[1, 2]
            l20, l21, l22 = P[2, 0], P[2, 1], P[2, 2]
            d = q[i]
            px = place_p[i, 0] + d * (l00 * ux + l01 * uy + l02 * uz)
            py = place_p[i, 1] + d * (l10 * ux + l11 * uy + l12 * uz)
            pz = place_p[i, 2] + d * (l20 * ux + l21 * uy + l22 * uz)
        j = parent[i]
        if j < 0:
            oR[i, 0, 0], oR[i, 0, 1], oR[i, 0, 2] = l00, l01, l02
            oR[i, 1, 0], oR[i, 1, 1], oR[i, 1, 2] = l10, l11, l12
            oR[i, 2, 0], oR[i, 2, 1], oR[i, 2, 2] = l20, l21, l22
            op[i, 0], op[i, 1], op[i, 2] = px, py, pz
        else:
            for a in range(3):
                A0, A1, A2 = oR[j, a, 0], oR[j, a, 1], oR[j, a, 2]
                op[i, a] = op[j, a] + A0 * px + A1 * py + A2 * pz
                oR[i, a, 0] = A0 * l00 + A1 * l10 + A2 * l20
                oR[i, a, 1] = A0 * l01 + A1 * l11 + A2 * l21
                oR[i, a, 2] = A0 * l02 + A1 * l12 + A2 * l22
        for a in range(3):
            oa[i, a] = oR[i, a, 0] * ux + oR[i, a, 1] * uy + oR[i, a, 2] * uz


@_jit()
def _point(c_joint, c_p, oR, op, c, side):
    """World position of the origin of side ``side`` (0, 1) of closure ``c``."""
    j = c_joint[c, side]
    p0, p1, p2 = c_p[c, side, 0], c_p[c, side, 1], c_p[c, side, 2]
    if j < 0:
        return p0, p1, p2
    return (op[j, 0] + oR[j, 0, 0] * p0 + oR[j, 0, 1] * p1 + oR[j, 0, 2] * p2,
            op[j, 1] + oR[j, 1, 0] * p0 + oR[j, 1, 1] * p1 + oR[j, 1, 2] * p2,
            op[j, 2] + oR[j, 2, 0] * p0 + oR[j, 2, 1] * p1 + oR[j, 2, 2] * p2)


@_jit()
def _frame_rotation(c_joint, c_R, oR, c, side, out):
    j = c_joint[c, side]
    for a in range(3):
        for b in range(3):
            if j < 0:
                out[a, b] = c_R[c, side, a, b]
            else:
                out[a, b] = oR[j, a, 0] * c_R[c, side, 0, b] + oR[j, a, 1] * c_R[c, side, 1, b] \
                    + oR[j, a, 2] * c_R[c, side, 2, b]


@_jit()
def _residual(c_joint, c_R, c_p, c_rigid, c_row, oR, op, r, m3, v3):
    """The closure residuals into ``r`` (m,) at the placed frames; returns their largest
    magnitude. Per point joint the position of frame 1 minus frame 2 (m); per weld also the
    orientation error ``-R1 log3(R1^T R2)`` (rad)."""
    for c in range(c_rigid.shape[0]):
        row = c_row[c]
        x1, y1, z1 = _point(c_joint, c_p, oR, op, c, 0)
        x2, y2, z2 = _point(c_joint, c_p, oR, op, c, 1)
        r[row], r[row + 1], r[row + 2] = x1 - x2, y1 - y2, z1 - z2
        if c_rigid[c]:
            R1, R2, rel = m3[0], m3[1], m3[2]
            _frame_rotation(c_joint, c_R, oR, c, 0, R1)
            _frame_rotation(c_joint, c_R, oR, c, 1, R2)
            for a in range(3):
                for b in range(3):
                    rel[a, b] = R1[0, a] * R2[0, b] + R1[1, a] * R2[1, b] + R1[2, a] * R2[2, b]
            _log3(rel, v3)
            for a in range(3):
                r[row + 3 + a] = -(R1[a, 0] * v3[0] + R1[a, 1] * v3[1] + R1[a, 2] * v3[2])
    return _max_abs(r)


@_jit()
def _closure_jacobian(kind, ancestor, c_joint, c_p, c_rigid, c_row, oR, op, oa, J):
    """The closure Jacobian into ``J`` (m, nj) at the placed frames: per closure, frame 1's
    Jacobian minus frame 2's (linear velocity of its origin, then angular velocity for a weld;
    world axes: pinocchio's ``LOCAL_WORLD_ALIGNED``)."""
    nj = kind.shape[0]
    J[:, :] = 0.0
    for c in range(c_rigid.shape[0]):
        row = c_row[c]
        rigid = c_rigid[c]
        for side in range(2):
            j = c_joint[c, side]
            if j < 0:
                continue
            sign = 1.0 if side == 0 else -1.0
            x, y, z = _point(c_joint, c_p, oR, op, c, side)
            for i in range(nj):
                if not ancestor[j, i]:
                    continue
                ax, ay, az = oa[i, 0], oa[i, 1], oa[i, 2]
                if kind[i] == REVOLUTE_JOINT:
                    cx, cy, cz = _cross(ax, ay, az, x - op[i, 0], y - op[i, 1], z - op[i, 2])
                    J[row, i] += sign * cx
                    J[row + 1, i] += sign * cy
                    J[row + 2, i] += sign * cz
                    if rigid:
                        J[row + 3, i] += sign * ax
                        J[row + 4, i] += sign * ay
                        J[row + 5, i] += sign * az
                else:
                    J[row, i] += sign * ax
                    J[row + 1, i] += sign * ay
                    J[row + 2, i] += sign * az


# ---------------------------------------------------------------------------------- linear algebra
# ``J_p`` is factored by Householder reflections in the order and on the rows an elimination
# plan gives (:func:`elimination_plan`): a loop's own passive joints, which no other closure's
# rows see, are eliminated on that loop's rows alone, then the joints shared by several loops on
# what is left of all of them (the Delta: two 6 x 4 blocks, then 4 x 4 for the platform's branch,
# instead of one dense 12 x 12). A plan is an int array: ``p``, then per elimination step ``k``
# the column ``col[k]`` (a passive position), its pivot row ``piv[k]``, the start of its row list
# and of its update list (absolute indices into the plan, ``p + 1`` each: the last ends the
# list), then the row lists (the pivot first, then the rows the reflector mixes into it, in
# increasing order) and the update lists (the later steps whose columns the reflector changes).
# R's entry of steps ``(k, j)`` is ``QR[piv[k], col[j]]``; the reflectors are stored on their
# rows in their column. The dense plan (every row in order, every later column) is LAPACK's
# ``geqrf`` layout and order, operation for operation.

def dense_plan(m: int, p: int) -> np.ndarray:
    """The elimination plan of a dense ``J_p`` (m, p): step ``k`` on column ``k``, pivot row
    ``k``, rows ``k..m-1``, every later column (plain Householder QR)."""
    return _plan(list(range(p)), [list(range(k, m)) for k in range(p)], [list(range(k + 1, p)) for k in range(p)])


def elimination_plan(structure: np.ndarray, closure_rows: np.ndarray) -> np.ndarray:
    """The elimination plan (module comment above) of a ``J_p`` whose structurally non-zero
    entries are ``structure`` (m, p) bool, its rows grouped by closure (``closure_rows``
    (nc + 1,): each closure's first row, then m). Columns seen by one closure's rows only come
    first, closure by closure, then the others in their order; each step's reflector takes the
    column's structurally non-zero rows not yet a pivot (the first the pivot), and changes the
    later columns non-zero on any of them, which then fill in on all of them (symbolic
    Householder). The dense plan where ``m < p`` or a column runs out of rows (a ``J_p`` that
    loses rank whatever the state: the factorisation says so at its pivot)."""
    S = np.array(structure, dtype=bool)
    m, p = S.shape
    if m < p:
        return dense_plan(m, p)
    closure_of_row = np.searchsorted(np.asarray(closure_rows), np.arange(m), side="right") - 1
    seen = [set(closure_of_row[S[:, k]].tolist()) for k in range(p)]
    private = sorted((min(s), k) for k, s in enumerate(seen) if len(s) == 1)
    order = [k for _, k in private] + [k for k, s in enumerate(seen) if len(s) != 1]
    free = np.ones(m, dtype=bool)
    rows, updates = [], []
    for step, c in enumerate(order):
        hit = np.flatnonzero(S[:, c] & free)
        if not len(hit):
            return dense_plan(m, p)
        later = [j for j in range(step + 1, p) if S[hit, order[j]].any()]
        for j in later:
            S[hit, order[j]] = True
        free[hit[0]] = False
        rows.append(hit.tolist())
        updates.append(later)
    return _plan(order, rows, updates)


def _plan(order, rows, updates) -> np.ndarray:
    """The plan's int array from the columns in elimination order, each step's rows (pivot first)
    and its update list (later steps)."""
    p = len(order)
    head = 1 + 4 * p + 2
    rows_at = head + np.concatenate([[0], np.cumsum([len(r) for r in rows])]).astype(np.int64)
    updates_at = rows_at[-1] + np.concatenate([[0], np.cumsum([len(u) for u in updates])]).astype(np.int64)
    flat = [np.array([p]), np.array(order), np.array([r[0] for r in rows]), rows_at, updates_at,
            *[np.array(r) for r in rows], *[np.array(u) for u in updates]]
    return np.concatenate([np.asarray(x, dtype=np.int64).reshape(-1) for x in flat])


@_jit()
def _householder(plan, A, tau):
    """Householder QR of ``A`` (m, p), m >= p, in place by the elimination ``plan`` (the
    comment above): R on its pivots' rows, each reflector on its rows below its pivot, their
    factors in ``tau`` (p,)."""
    p = plan[0]
    for k in range(p):
        c, lo, hi = plan[1 + k], plan[1 + 2 * p + k], plan[2 + 2 * p + k]
        r0 = plan[lo]
        norm = 0.0
        for t in range(lo, hi):
            norm += A[plan[t], c] * A[plan[t], c]
        norm = np.sqrt(norm)
        if norm == 0.0:
            tau[k] = 0.0
            continue
        alpha = -norm if A[r0, c] >= 0.0 else norm
        v0 = A[r0, c] - alpha
        for t in range(lo + 1, hi):
            A[plan[t], c] /= v0
        tau[k] = -v0 / alpha
        A[r0, c] = alpha
        for u in range(plan[2 + 3 * p + k], plan[3 + 3 * p + k]):
            j = plan[1 + plan[u]]
            s = A[r0, j]
            for t in range(lo + 1, hi):
                s += A[plan[t], c] * A[plan[t], j]
            s *= tau[k]
            A[r0, j] -= s
            for t in range(lo + 1, hi):
                A[plan[t], j] -= s * A[plan[t], c]


@_jit()
def _qr_solve(plan, QR, tau, b, x):
    """``x = R^-1 Q^T b`` (p,) of a Householder QR by ``plan`` (:func:`_householder`); ``b``
    (m,) is overwritten."""
    p = plan[0]
    for k in range(p):
        c, lo, hi = plan[1 + k], plan[1 + 2 * p + k], plan[2 + 2 * p + k]
        r0 = plan[lo]
        s = b[r0]
        for t in range(lo + 1, hi):
            s += QR[plan[t], c] * b[plan[t]]
        s *= tau[k]
        b[r0] -= s
        for t in range(lo + 1, hi):
            b[plan[t]] -= s * QR[plan[t], c]
    for k in range(p - 1, -1, -1):
        r0 = plan[1 + p + k]
        s = b[r0]
        for u in range(plan[2 + 3 * p + k], plan[3 + 3 * p + k]):
            j = plan[1 + plan[u]]
            s -= QR[r0, j] * x[j]
        x[plan[1 + k]] = s / QR[r0, plan[1 + k]]


@_jit()
def _r_condition(plan, QR, Rinv):
    """``cond_1(R)`` of the triangular factor (inf where a diagonal entry is 0): within a factor
    ``p`` of ``cond_2(J_p)``. ``Rinv`` (p, p) scratch, in elimination order. ``R^-1`` is built
    row by row from the last (row ``k`` from the rows below it that ``R``'s row ``k`` reaches:
    its update list), each row's entries independent of one another, not column by column,
    where each entry waits on the division before it."""
    p = plan[0]
    for k in range(p):
        if QR[plan[1 + p + k], plan[1 + k]] == 0.0:
            return np.inf
    for k in range(p - 1, -1, -1):
        rk = plan[1 + p + k]
        dk = 1.0 / QR[rk, plan[1 + k]]
        for j in range(k + 1, p):
            Rinv[k, j] = 0.0
        for u in range(plan[2 + 3 * p + k], plan[3 + 3 * p + k]):
            i = plan[u]
            rki = QR[rk, plan[1 + i]]
            for j in range(i, p):
                Rinv[k, j] += rki * Rinv[i, j]
        Rinv[k, k] = dk
        for j in range(k + 1, p):
            Rinv[k, j] *= -dk
    norm, inorm = 0.0, 0.0
    for j in range(p):
        cj = plan[1 + j]
        s, t = 0.0, 0.0
        for i in range(j + 1):
            s += abs(QR[plan[1 + p + i], cj])
            t += abs(Rinv[i, j])
        norm, inorm = max(norm, s), max(inorm, t)
    return norm * inorm


@_jit()
def _factor(plan, pas, J, QR, tau):
    """Householder QR of ``J_p`` (the passive columns of ``J``) into ``QR``, ``tau`` by
    ``plan``; False where ``J_p`` loses rank (a diagonal entry of R below 1e-10 of the largest)."""
    m, p = QR.shape
    for i in range(m):
        for k in range(p):
            QR[i, k] = J[i, pas[k]]
    _householder(plan, QR, tau)
    top = 0.0
    for k in range(p):
        top = max(top, abs(QR[plan[1 + p + k], plan[1 + k]]))
    for k in range(p):
        if not abs(QR[plan[1 + p + k], plan[1 + k]]) > 1e-10 * top:
            return False
    return True


@_jit()
def _newton_step(plan, pas, QR, tau, r, b, x, q):
    """``q_p -= J_p^+ r`` with the factors ``QR``, ``tau``; returns the step's largest entry."""
    m, p = QR.shape
    for i in range(m):
        b[i] = -r[i]
    _qr_solve(plan, QR, tau, b, x)
    step = 0.0
    for k in range(p):
        q[pas[k]] += x[k]
        step = max(step, abs(x[k]))
    return step


# ---------------------------------------------------------------------------------- rates and forces
@_jit()
def _rates(parent, kind, op, oa, v, qdd, gx, gy, gz, w, dp, al, dd):
    """World angular velocity ``w``, origin velocity ``dp``, angular acceleration ``al`` and
    classical origin acceleration ``dd`` (each (nj, 3)) of every joint frame at the placed
    configuration, joint rates ``v`` and accelerations ``qdd`` (nj,); the world accelerates by
    ``(gx, gy, gz)`` (``-g``: gravity)."""
    for i in range(parent.shape[0]):
        j = parent[i]
        ax, ay, az = oa[i, 0], oa[i, 1], oa[i, 2]
        if j < 0:
            wx = wy = wz = vx = vy = vz = alx = aly = alz = 0.0
            dx, dy, dz = gx, gy, gz
            tx = ty = tz = 0.0
        else:
            rx, ry, rz = op[i, 0] - op[j, 0], op[i, 1] - op[j, 1], op[i, 2] - op[j, 2]
            wx, wy, wz = w[j, 0], w[j, 1], w[j, 2]
            alx, aly, alz = al[j, 0], al[j, 1], al[j, 2]
            cx, cy, cz = _cross(wx, wy, wz, rx, ry, rz)
            vx, vy, vz = dp[j, 0] + cx, dp[j, 1] + cy, dp[j, 2] + cz
            ex, ey, ez = _cross(alx, aly, alz, rx, ry, rz)
            fx, fy, fz = _cross(wx, wy, wz, cx, cy, cz)
            dx, dy, dz = dd[j, 0] + ex + fx, dd[j, 1] + ey + fy, dd[j, 2] + ez + fz
            tx, ty, tz = _cross(wx, wy, wz, ax, ay, az)
        vi, ai = v[i], qdd[i]
        if kind[i] == REVOLUTE_JOINT:
            wx, wy, wz = wx + ax * vi, wy + ay * vi, wz + az * vi
            alx, aly, alz = alx + tx * vi + ax * ai, aly + ty * vi + ay * ai, alz + tz * vi + az * ai
        else:
            vx, vy, vz = vx + ax * vi, vy + ay * vi, vz + az * vi
            dx, dy, dz = dx + 2.0 * tx * vi + ax * ai, dy + 2.0 * ty * vi + ay * ai, dz + 2.0 * tz * vi + az * ai
        w[i, 0], w[i, 1], w[i, 2] = wx, wy, wz
        dp[i, 0], dp[i, 1], dp[i, 2] = vx, vy, vz
        al[i, 0], al[i, 1], al[i, 2] = alx, aly, alz
        dd[i, 0], dd[i, 1], dd[i, 2] = dx, dy, dz


@_jit()
def _drift(c_joint, c_p, c_rigid, c_row, oR, op, w, al, dd, gamma):
    """``gamma = Jdot v`` (m,): the closure frames' relative classical acceleration (and angular
    acceleration, for a weld) from the rates ``w``, ``al``, ``dd`` of :func:`_rates` at zero
    joint acceleration and no gravity."""
    for c in range(c_rigid.shape[0]):
        row = c_row[c]
        for k in range(c_row[c + 1] - row):
            gamma[row + k] = 0.0
        for side in range(2):
            j = c_joint[c, side]
            if j < 0:
                continue
            sign = 1.0 if side == 0 else -1.0
            x, y, z = _point(c_joint, c_p, oR, op, c, side)
            dx, dy, dz = x - op[j, 0], y - op[j, 1], z - op[j, 2]
            ex, ey, ez = _cross(al[j, 0], al[j, 1], al[j, 2], dx, dy, dz)
            cx, cy, cz = _cross(w[j, 0], w[j, 1], w[j, 2], dx, dy, dz)
            fx, fy, fz = _cross(w[j, 0], w[j, 1], w[j, 2], cx, cy, cz)
            gamma[row] += sign * (dd[j, 0] + ex + fx)
            gamma[row + 1] += sign * (dd[j, 1] + ey + fy)
            gamma[row + 2] += sign * (dd[j, 2] + ez + fz)
            if c_rigid[c]:
                for k in range(3):
                    gamma[row + 3 + k] += sign * al[j, k]


@_jit()
def _actuated_jacobians(parent, kind, oR, op, oa, W, wv, ww, Jv, Jw):
    """Each joint frame's actuated Jacobian at its origin, in its own axes, into ``Jv``
    (linear) and ``Jw`` (angular) (nj, 3, n): the frame moves by ``Jv[i] @ Thetad`` along
    ``v = W Thetad``. Built down the tree in world axes (``wv``, ``ww``)."""
    n = W.shape[1]
    for i in range(parent.shape[0]):
        j = parent[i]
        ax, ay, az = oa[i, 0], oa[i, 1], oa[i, 2]
        revolute = kind[i] == REVOLUTE_JOINT
        rx = ry = rz = 0.0
        if j >= 0:
            rx, ry, rz = op[i, 0] - op[j, 0], op[i, 1] - op[j, 1], op[i, 2] - op[j, 2]
        for c in range(n):
            if j < 0:
                vx = vy = vz = wx = wy = wz = 0.0
            else:
                wx, wy, wz = ww[j, 0, c], ww[j, 1, c], ww[j, 2, c]
                cx, cy, cz = _cross(wx, wy, wz, rx, ry, rz)
                vx, vy, vz = wv[j, 0, c] + cx, wv[j, 1, c] + cy, wv[j, 2, c] + cz
            s = W[i, c]
            if revolute:
                wx, wy, wz = wx + ax * s, wy + ay * s, wz + az * s
            else:
                vx, vy, vz = vx + ax * s, vy + ay * s, vz + az * s
            wv[i, 0, c], wv[i, 1, c], wv[i, 2, c] = vx, vy, vz
            ww[i, 0, c], ww[i, 1, c], ww[i, 2, c] = wx, wy, wz
            for k in range(3):
                Jv[i, k, c] = oR[i, 0, k] * vx + oR[i, 1, k] * vy + oR[i, 2, k] * vz
                Jw[i, k, c] = oR[i, 0, k] * wx + oR[i, 1, k] * wy + oR[i, 2, k] * wz


@_jit()
def _body_rows(oR, w, al, dd, Jv, Jw, rows):
    """The actuated regressor ``W^T Y_tree`` (n, 10 nj) into ``rows`` from the rates of
    :func:`_rates` (gravity in ``dd``) and the actuated Jacobians: ``tau = rows @ pi`` with
    ``pi`` ten values per body (mass, first moment ``h``, inertia ``I`` about the joint frame's
    origin, in its axes: pinocchio's dynamic parameters). Per body, in its axes:
    ``f = m acc + [alpha]x h + [w]x[w]x h`` and ``n = I alpha + w x (I w) + h x acc``, seen by
    the actuators through ``J_i W``."""
    n = Jv.shape[2]
    for i in range(oR.shape[0]):
        R = oR[i]
        wx = R[0, 0] * w[i, 0] + R[1, 0] * w[i, 1] + R[2, 0] * w[i, 2]
        wy = R[0, 1] * w[i, 0] + R[1, 1] * w[i, 1] + R[2, 1] * w[i, 2]
        wz = R[0, 2] * w[i, 0] + R[1, 2] * w[i, 1] + R[2, 2] * w[i, 2]
        bx = R[0, 0] * al[i, 0] + R[1, 0] * al[i, 1] + R[2, 0] * al[i, 2]
        by = R[0, 1] * al[i, 0] + R[1, 1] * al[i, 1] + R[2, 1] * al[i, 2]
        bz = R[0, 2] * al[i, 0] + R[1, 2] * al[i, 1] + R[2, 2] * al[i, 2]
        cx = R[0, 0] * dd[i, 0] + R[1, 0] * dd[i, 1] + R[2, 0] * dd[i, 2]
        cy = R[0, 1] * dd[i, 0] + R[1, 1] * dd[i, 1] + R[2, 1] * dd[i, 2]
        cz = R[0, 2] * dd[i, 0] + R[1, 2] * dd[i, 1] + R[2, 2] * dd[i, 2]
        # A = [alpha]x + [w]x[w]x: f's h part
        a00, a01, a02 = -(wy * wy + wz * wz), wx * wy - bz, wx * wz + by
        a10, a11, a12 = wx * wy + bz, -(wx * wx + wz * wz), wy * wz - bx
        a20, a21, a22 = wx * wz - by, wy * wz + bx, -(wx * wx + wy * wy)
        # n's inertia part L(alpha) + [w]x L(w) over (Ixx, Ixy, Iyy, Ixz, Iyz, Izz), L(x) I = I x
        b0 = (bx, by - wz * wx, -wz * wy, bz + wy * wx, wy * wy - wz * wz, wy * wz)
        b1 = (wz * wx, bx + wz * wy, by, wz * wz - wx * wx, bz - wx * wy, -wx * wz)
        b2 = (-wy * wx, wx * wx - wy * wy, wx * wy, bx - wy * wz, by + wx * wz, bz)
        base = 10 * i
        for k in range(n):
            u0, u1, u2 = Jv[i, 0, k], Jv[i, 1, k], Jv[i, 2, k]
            s0, s1, s2 = Jw[i, 0, k], Jw[i, 1, k], Jw[i, 2, k]
            rows[k, base] = u0 * cx + u1 * cy + u2 * cz
            # s . (h x acc) = h . (acc x s)
            rows[k, base + 1] = u0 * a00 + u1 * a10 + u2 * a20 + (cy * s2 - cz * s1)
            rows[k, base + 2] = u0 * a01 + u1 * a11 + u2 * a21 + (cz * s0 - cx * s2)
            rows[k, base + 3] = u0 * a02 + u1 * a12 + u2 * a22 + (cx * s1 - cy * s0)
            for c in range(6):
                rows[k, base + 4 + c] = s0 * b0[c] + s1 * b1[c] + s2 * b2[c]


# ---------------------------------------------------------------------------------- per sample
@_jit()
def _predict(act, last_q, last_W, last_valid, Theta, base, q):
    """The Newton start ``q`` (nj,) for ``Theta`` from ``base`` (a configuration near it): the
    last solved state's velocity map carries ``base`` to ``Theta`` to first order, where the
    last state is within :data:`PREDICT_RADIUS` of ``base`` and ``base`` of ``Theta``. Returns whether it did (then the
    last state's factors of ``J_p`` serve Newton too)."""
    _copy(base, q)
    if not last_valid[0]:
        return False
    for i in range(q.shape[0]):
        if abs(base[i] - last_q[i]) > PREDICT_RADIUS:
            return False
    for k in range(act.shape[0]):
        if abs(Theta[k] - base[act[k]]) > PREDICT_RADIUS:
            return False
    for k in range(act.shape[0]):
        d = Theta[k] - base[act[k]]
        if d != 0.0:
            for i in range(q.shape[0]):
                q[i] += last_W[i, k] * d
    return True


@_jit()
def _curvature(parent, kind, act, pas, plan, c_joint, c_p, c_rigid, c_row, oR, op, oa, last_W, QR, tau, b, x, w, dp, al, dd,
               zero, Theta, base, v, q):
    """The second-order term of the prediction (:func:`_predict`) added to ``q``: along the step
    ``d = Theta - base_a`` the passive joints curve by ``q_p'' = -J_p^+ gamma(W d)`` (the closure's
    drift at the rates ``W d``), so ``q += q'' / 2``. The frames placed, the velocity map and
    the factors of ``J_p`` are the last solved sample's (the workspace as the last call left it);
    one drift and one solve, against a chord iteration's placements and residual: a start about
    ``|d|`` closer, one iteration fewer. ``v`` (nj,) scratch."""
    n = act.shape[0]
    for i in range(v.shape[0]):
        s = 0.0
        for k in range(n):
            s += last_W[i, k] * (Theta[k] - base[act[k]])
        v[i] = s
    _rates(parent, kind, op, oa, v, zero, 0.0, 0.0, 0.0, w, dp, al, dd)
    _drift(c_joint, c_p, c_rigid, c_row, oR, op, w, al, dd, b)
    _qr_solve(plan, QR, tau, b, x)
    for k in range(pas.shape[0]):
        q[pas[k]] -= 0.5 * x[k]


@_jit()
def _close(parent, kind, axis, place_R, place_p, ancestor, pas, plan, c_joint, c_R, c_p, c_rigid, c_row, tolerance, singular,
           QR, tau, residual, oR, op, oa, J, r, b, x, pp, m3, v3, chord, max_iterations, q):
    """Newton on the passive joints of ``q`` (in place) until the closure residual is within
    ``tolerance``: first with the last sample's factors of ``J_p`` (``chord``: a start predicted
    from that sample gains about three digits an iteration at 250 Hz, no Jacobian needed), then,
    if that stalls, with the Jacobian at each iterate. Leaves the frames placed, the closure
    Jacobian and the QR of ``J_p`` at the solution (for ``W``, ``a0`` and the next sample).
    Returns a status code."""
    _placements(parent, kind, axis, place_R, place_p, q, oR, op, oa)
    if r.shape[0] == 0:
        return OK
    res = _residual(c_joint, c_R, c_p, c_rigid, c_row, oR, op, r, m3, v3)
    if res > tolerance and chord:
        for _ in range(6):
            step = _newton_step(plan, pas, QR, tau, r, b, x, q)
            _placements(parent, kind, axis, place_R, place_p, q, oR, op, oa)
            last, res = res, _residual(c_joint, c_R, c_p, c_rigid, c_row, oR, op, r, m3, v3)
            if res <= tolerance or not (step < 10.0 and res < 0.1 * last):
                break
    if res > tolerance and np.isfinite(res):
        for _ in range(max_iterations):
            _closure_jacobian(kind, ancestor, c_joint, c_p, c_rigid, c_row, oR, op, oa, J)
            if not _factor(plan, pas, J, QR, tau):
                return SINGULAR
            step = _newton_step(plan, pas, QR, tau, r, b, x, q)
            _placements(parent, kind, axis, place_R, place_p, q, oR, op, oa)
            res = _residual(c_joint, c_R, c_p, c_rigid, c_row, oR, op, r, m3, v3)
            if res <= tolerance or not np.isfinite(step) or step > 10.0:
                break
    if not res <= max(tolerance, 1e-10):
        residual[0] = res
        return NO_ASSEMBLY
    _closure_jacobian(kind, ancestor, c_joint, c_p, c_rigid, c_row, oR, op, oa, J)
    _factor(plan, pas, J, QR, tau)
    if not _r_condition(plan, QR, pp) < singular:
        return SINGULAR
    return OK


@_jit()
def _velocity_map(act, pas, plan, J, QR, tau, b, x, W):
    """``W`` (nj, n) with ``v = W Thetad``: ``W_a = I``, ``W_p = -J_p^+ J_a`` (the QR of ``J_p``)."""
    n, p, m = act.shape[0], pas.shape[0], J.shape[0]
    W[:, :] = 0.0
    for k in range(n):
        W[act[k], k] = 1.0
    if m:
        for c in range(n):
            for i in range(m):
                b[i] = J[i, act[c]]
            _qr_solve(plan, QR, tau, b, x)
            for k in range(p):
                W[pas[k], c] = -x[k]


@_jit()
def _state(parent, kind, axis, place_R, place_p, ancestor, act, pas, plan, c_joint, c_R, c_p, c_rigid, c_row, home_q,
           tolerance, singular, last_q, last_W, last_valid, QR, tau, residual, oR, op, oa, J, r, b, x, pp, m3, v3,
           w, dp, al, dd, zero, Theta, Thetad, Thetadd, base, has_base, max_iterations, q, W, v, a):
    """One sample: ``q`` closed from ``base`` (where ``has_base``, else the last state, else
    home), ``W``, ``v = W Thetad``, ``a = W Thetadd + a0`` (``a0_p = -J_p^+ gamma``); the frames
    placed at ``q`` (:func:`_close`). The workspace then holds this sample's closure state.
    Returns a status code."""
    nj, n, p, m = parent.shape[0], act.shape[0], pas.shape[0], r.shape[0]
    if has_base:
        chord = _predict(act, last_q, last_W, last_valid, Theta, base, q)
    elif last_valid[0]:
        chord = _predict(act, last_q, last_W, last_valid, Theta, last_q, q)
    else:
        chord = False
        _copy(home_q, q)
    for k in range(n):
        q[act[k]] = Theta[k]
    if chord and m:
        _curvature(parent, kind, act, pas, plan, c_joint, c_p, c_rigid, c_row, oR, op, oa, last_W, QR, tau, b, x, w, dp,
                   al, dd, zero, Theta, base if has_base else last_q, v, q)
    last_valid[0] = 0
    code = _close(parent, kind, axis, place_R, place_p, ancestor, pas, plan, c_joint, c_R, c_p, c_rigid, c_row, tolerance,
                  singular, QR, tau, residual, oR, op, oa, J, r, b, x, pp, m3, v3, chord, max_iterations, q)
    if code == NO_ASSEMBLY and chord:      # the prediction led astray: Newton from the start as given
        _copy(base if has_base else last_q, q)
        for k in range(n):
            q[act[k]] = Theta[k]
        code = _close(parent, kind, axis, place_R, place_p, ancestor, pas, plan, c_joint, c_R, c_p, c_rigid, c_row,
                      tolerance, singular, QR, tau, residual, oR, op, oa, J, r, b, x, pp, m3, v3, False,
                      max_iterations, q)
    if code != OK:
        return code
    _velocity_map(act, pas, plan, J, QR, tau, b, x, W)
    for i in range(nj):
        s, t = 0.0, 0.0
        for c in range(n):
            s += W[i, c] * Thetad[c]
            t += W[i, c] * Thetadd[c]
        v[i], a[i] = s, t
    if m:
        _rates(parent, kind, op, oa, v, zero, 0.0, 0.0, 0.0, w, dp, al, dd)
        _drift(c_joint, c_p, c_rigid, c_row, oR, op, w, al, dd, b)
        _qr_solve(plan, QR, tau, b, x)
        for k in range(p):
            a[pas[k]] -= x[k]
    _copy(q, last_q)
    for i in range(nj):
        _copy(W[i], last_W[i])
    last_valid[0] = 1
    return OK


@_jit()
def _rows(parent, kind, gravity, oR, op, oa, W, v, a, w, dp, al, dd, wv, ww, Jv, Jw, rows):
    """The actuated regressor rows (n, 10 nj) of a solved sample (:func:`_body_rows`)."""
    _rates(parent, kind, op, oa, v, a, -gravity[0], -gravity[1], -gravity[2], w, dp, al, dd)
    _actuated_jacobians(parent, kind, oR, op, oa, W, wv, ww, Jv, Jw)
    _body_rows(oR, w, al, dd, Jv, Jw, rows)


@_jit(nogil=True)
def motion_batch(ti, tf, wf, wi, Theta, Thetad, Thetadd, guess, has_guess, want_rows, max_iterations, Q, V, A, Ws,
                 rows):
    """A batch of samples (N, n each): the tree configurations ``Q`` (N, nj), rates ``V``,
    accelerations ``A`` (N, nj), velocity maps ``Ws`` (N, nj, n) and, if ``want_rows``, the
    actuated regressor rows (N, n, 10 nj) into ``rows``. Sample ``k`` starts Newton from
    ``guess[k]`` where ``has_guess[k]``, else from the last sample solved (else home), predicted
    to first order (``_predict``). Stops at the first sample that fails: ``ws.status`` says
    how and where. The workspace keeps the last sample's closure state. ``ti``, ``tf``: the
    compiled tree (:class:`CompiledTree`), ``wf``, ``wi``: the workspace (:class:`Workspace`)."""
    t, s = _tree(ti, tf), _workspace(ti, wf, wi)
    s.status[0] = OK
    for k in range(Theta.shape[0]):
        code = _state(t.parent, t.kind, t.axis, t.place_R, t.place_p, t.ancestor, t.act, t.pas, t.plan, t.c_joint, t.c_R,
                      t.c_p, t.c_rigid, t.c_row, t.home_q, t.tolerance, t.singular, s.last_q, s.last_W,
                      s.last_valid, s.QR, s.tau, s.residual, s.oR, s.op, s.oa, s.J, s.r, s.b, s.x, s.pp, s.m3,
                      s.v3, s.omega, s.dp, s.alpha, s.ddp, s.zero, Theta[k], Thetad[k], Thetadd[k], guess[k],
                      has_guess[k], max_iterations, Q[k], Ws[k], V[k], A[k])
        if code != OK:
            s.status[0], s.status[1] = code, k
            return
        if want_rows:
            _rows(t.parent, t.kind, t.gravity, s.oR, s.op, s.oa, Ws[k], V[k], A[k], s.omega, s.dp, s.alpha, s.ddp,
                  s.wv, s.ww, s.Jv, s.Jw, rows[k])


@_jit()
def _mass_matrix(Jv, Jw, pi, Jm, F, M):
    """``M = sum_i (J_i W)^T I_i (J_i W) + diag(Jm)`` (n, n): each body's spatial inertia about
    its joint frame's origin, in its axes (``pi``: ten values per body), seen through its
    actuated Jacobians ``Jv``, ``Jw`` (nj, 3, n). ``F`` (6, n) scratch."""
    nj, n = Jv.shape[0], Jv.shape[2]
    M[:, :] = 0.0
    for i in range(nj):
        b = 10 * i
        mass, hx, hy, hz = pi[b], pi[b + 1], pi[b + 2], pi[b + 3]
        Ixx, Ixy, Iyy, Ixz, Iyz, Izz = pi[b + 4], pi[b + 5], pi[b + 6], pi[b + 7], pi[b + 8], pi[b + 9]
        for c in range(n):
            vx, vy, vz = Jv[i, 0, c], Jv[i, 1, c], Jv[i, 2, c]
            wx, wy, wz = Jw[i, 0, c], Jw[i, 1, c], Jw[i, 2, c]
            # momentum f = m v + w x h, moment n = h x v + I w
            F[0, c] = mass * vx + (wy * hz - wz * hy)
            F[1, c] = mass * vy + (wz * hx - wx * hz)
            F[2, c] = mass * vz + (wx * hy - wy * hx)
            F[3, c] = (hy * vz - hz * vy) + Ixx * wx + Ixy * wy + Ixz * wz
            F[4, c] = (hz * vx - hx * vz) + Ixy * wx + Iyy * wy + Iyz * wz
            F[5, c] = (hx * vy - hy * vx) + Ixz * wx + Iyz * wy + Izz * wz
        for r in range(n):
            for c in range(r, n):
                M[r, c] += (Jv[i, 0, r] * F[0, c] + Jv[i, 1, r] * F[1, c] + Jv[i, 2, r] * F[2, c]
                            + Jw[i, 0, r] * F[3, c] + Jw[i, 1, r] * F[4, c] + Jw[i, 2, r] * F[5, c])
    for r in range(n):
        M[r, r] += Jm[r]
        for c in range(r):
            M[r, c] = M[c, r]


@_jit(nogil=True)
def plant_dynamics(ti, tf, wf, wi, Theta, Thetad, guess, has_guess, pi, Jm, max_iterations, q, M, bias):
    """The actuated dynamics of one state (the plant, once per period): the configuration ``q``
    (nj,), ``M = sum_i (J_i W)^T I_i (J_i W) + diag(Jm)`` (n, n) and ``bias`` (n,) (velocity
    terms and gravity) with the bodies' parameters ``pi`` (10 nj,). Newton starts from ``guess``
    (where ``has_guess``) or the last state, predicted to first order. Returns a status code.
    ``ti``, ``tf``: the compiled tree, ``wf``, ``wi``: the workspace."""
    t, s = _tree(ti, tf), _workspace(ti, wf, wi)
    n = t.act.shape[0]
    s.status[0] = OK
    code = _state(t.parent, t.kind, t.axis, t.place_R, t.place_p, t.ancestor, t.act, t.pas, t.plan, t.c_joint, t.c_R,
                  t.c_p, t.c_rigid, t.c_row, t.home_q, t.tolerance, t.singular, s.last_q, s.last_W,
                  s.last_valid, s.QR, s.tau, s.residual, s.oR, s.op, s.oa, s.J, s.r, s.b, s.x, s.pp, s.m3,
                  s.v3, s.omega, s.dp, s.alpha, s.ddp, s.zero, Theta, Thetad, s.zero[:n], guess, has_guess,
                  max_iterations, q, s.W1, s.v1, s.a1)
    if code != OK:
        s.status[0], s.status[1] = code, 0
        return code
    rows = s.rows1
    _rows(t.parent, t.kind, t.gravity, s.oR, s.op, s.oa, s.W1, s.v1, s.a1, s.omega, s.dp, s.alpha, s.ddp,
          s.wv, s.ww, s.Jv, s.Jw, rows)
    for k in range(n):
        acc = 0.0
        for c in range(rows.shape[1]):
            acc += rows[k, c] * pi[c]
        bias[k] = acc
    _mass_matrix(s.Jv, s.Jw, pi, Jm, s.F, M)
    return OK


@_jit(nogil=True)
def closure_at(ti, tf, wf, wi, q):
    """The closure residual ``r`` (m,) and Jacobian ``J`` (m, nj) into the workspace at ``q``
    (nj,), no Newton iterations (a configuration checked as it is)."""
    t, s = _tree(ti, tf), _workspace(ti, wf, wi)
    _placements(t.parent, t.kind, t.axis, t.place_R, t.place_p, q, s.oR, s.op, s.oa)
    if s.r.shape[0]:
        _residual(t.c_joint, t.c_R, t.c_p, t.c_rigid, t.c_row, s.oR, s.op, s.r, s.m3, s.v3)
        _closure_jacobian(t.kind, t.ancestor, t.c_joint, t.c_p, t.c_rigid, t.c_row, s.oR, s.op, s.oa, s.J)
