"""The Delta's hand model (:class:`~ident_hw.model.delta.Delta`) built from its description file,
checked against the file's generic model (:mod:`ident_hw.model.fast_path`).

The file follows the frames of ``configs/robots/delta.xml`` (its header): per limb ``i`` the
hinges ``q<i>`` (the arm, frame at ``A_i``), ``elbow<i>_y`` (the elbow's universal-joint cross,
at ``B_i``), ``elbow<i>_n`` (the rod, frame at ``B_i``, ``x`` along the rod, ``z = n_i``),
``wrist<i>_n`` (the wrist's cross, at ``P_i``) and ``wrist<i>_y``: on limb 1 the platform (frame
at ``P_1``, the site ``plat_centre`` at its centre ``p``), on limbs 2 and 3 the platform's yoke
at ``P_i``, welded to it. The hand model's values are pinocchio's reading of the file:

- geometry (m, rad): ``R`` and ``psi_i`` from the placement of ``q<i>``, ``L1`` from that of
  ``elbow1_y``, ``L2`` from that of ``wrist1_n``, ``r`` the distance of ``plat_centre`` from
  ``P_1``; gravity from ``<option gravity>`` (along ``-z``);
- bodies: the hand model has no universal-joint crosses and no yokes; it takes them lumped,
  which is exact for what they are. A cross turns with its limb's rod angle ``b_i`` only
  (angular velocity ``bd_i y_i``) and has its centre of mass at its joint: its mass is a point
  mass at ``B_i`` (the arm's tip) or at ``P_i`` (a point of the platform, which translates
  only), its inertia about ``y_i``, ``J``, is ``J`` added to the rod's inertia about its ``x``
  and its ``y`` axes (the rod turns with ``bd_i y_i + cd_i n_i``, whose components across
  ``n_i`` have squares summing to ``bd_i²``). A yoke welded to the platform is part of it. Each
  lumped body is expressed in the hand model's frame (the rod's at ``P_i`` with ``x = u_i``,
  ``y = -n_i``; the platform's at ``p`` with world axes);
- drive terms: per arm the MJCF ``damping`` (fv), ``frictionloss`` (fc), ``armature`` (Jm).

:func:`described_parameters` is the inverse for the identified values: the crosses and yokes as
the file has them, the rest in the arm, rod and platform bodies (what ``ident-hw export`` writes).
"""

from __future__ import annotations

import dataclasses
import math
from functools import lru_cache
from pathlib import Path
from typing import cast

import numpy as np
import pinocchio as pin

from .delta import ACTUATOR_NAMES, BODY_PARAMS, N_BODY_PARAMS, Delta, DeltaGeometry
from .described import DescribedRobot, DescriptionError, load_description, mjcf_gravity
from .fast_path import FAST_PATH_STATES, FastPath, check_fast_path

#: the tree joints of limb i (1-based): arm, elbow cross, rod, wrist cross, platform or its yoke
LIMB_JOINTS = tuple((f"q{i}", f"elbow{i}_y", f"elbow{i}_n", f"wrist{i}_n", f"wrist{i}_y") for i in (1, 2, 3))
CENTRE_SITE = "plat_centre"
#: the hand rod frame's axes (x = u, y = -n, z = n x u) of the file's rod axes (x = u, y = n x u, z = n)
_ROD_AXES = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
#: pinocchio's order of a body's ten values in that of the hand model (:data:`~ident_hw.model.delta.BODY_PARAMS`)
_PIN_ORDER = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
_TO_HAND = [_PIN_ORDER.index(p) for p in BODY_PARAMS]


def _hand(inertia: pin.Inertia) -> np.ndarray:
    return np.asarray(inertia.toDynamicParameters())[_TO_HAND]


def _moved(placement: pin.SE3, hand_values) -> np.ndarray:
    """Ten values in pinocchio's order of a body given by its ten hand-order values about frame
    B, expressed about frame A (``placement``: A_M_B). Linear in the values (a difference of two
    bodies, massless or not, is moved as they are): ``h_A = R h + m t``, ``I_A = R I R^T +
    m (|t|^2 1 - t t^T) + 2 (R h . t) 1 - R h t^T - t (R h)^T``."""
    v = np.asarray(hand_values, float)
    m, h = v[0], v[1:4]
    xx, xy, xz, yy, yz, zz = v[4:10]
    I = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    R, t = placement.rotation, placement.translation
    hr = R @ h
    IA = R @ I @ R.T + m * (t @ t * np.eye(3) - np.outer(t, t)) + 2 * (hr @ t) * np.eye(3) - np.outer(hr, t) - np.outer(t, hr)
    return np.array([m, *(hr + m * t), IA[0, 0], IA[0, 1], IA[1, 1], IA[0, 2], IA[1, 2], IA[2, 2]])


def tree_configuration(q, b, c) -> dict[str, np.ndarray]:
    """Tree joint values by joint name, each (N,), of arm angles ``q`` and the hand model's rod
    angles ``b``, ``c`` (each (N, 3), rad): per limb ``q, b - q, c, -c, -b``."""
    q, b, c = (np.atleast_2d(np.asarray(v, float)) for v in (q, b, c))
    out = {}
    for i, names in enumerate(LIMB_JOINTS):
        for name, value in zip(names, (q[:, i], b[:, i] - q[:, i], c[:, i], -c[:, i], -b[:, i])):
            out[name] = value
    return out


class _Reading:
    """The file's values the hand model is built of (:func:`read_values`)."""

    def __init__(self, path: Path):
        self.path = path
        self.model = load_description(path).model
        m = self.model
        missing = [n for names in LIMB_JOINTS for n in names if not m.existJointName(n)]
        if missing:
            raise DescriptionError(f"{path}: no joint {missing[0]!r}: a Delta file has the joints "
                                   f"{[n for names in LIMB_JOINTS for n in names]} (configs/robots/delta.xml)")
        if not m.existFrame(CENTRE_SITE):
            raise DescriptionError(f"{path}: no site {CENTRE_SITE!r} (the platform's centre, on the body of wrist1_y)")
        self.id = {n: m.getJointId(n) for names in LIMB_JOINTS for n in names}

    def placement(self, joint: str) -> pin.SE3:
        return self.model.jointPlacements[self.id[joint]]

    def inertia(self, joint: str) -> pin.Inertia:
        return self.model.inertias[self.id[joint]]

    def cross(self, joint: str) -> tuple[float, float]:
        """Mass and inertia about its ``y`` axis of a cross, whose centre of mass must be its joint."""
        I = self.inertia(joint)
        if np.abs(I.lever).max() > 1e-12:
            raise DescriptionError(f"{self.path}: the body of {joint!r} (a universal joint's cross) has its centre of "
                                   f"mass at {I.lever.tolist()} m from its joint; the Delta's hand model takes a cross "
                                   "centred on its joint")
        return float(I.mass), float(I.inertia[1, 1])


def read_values(path: str | Path) -> FastPath:
    """The hand model's geometry, its parameter vector (79,) and gravity (m/s², along ``-z``) read
    off a Delta file (the module docstring), unchecked (``agreement`` NaN).

    Raises:
        DescriptionError: a joint or the site missing, a cross off its joint, or a gravity not
            along ``-z``, naming the file.
    """
    path = Path(path)
    f = _Reading(path)
    gravity = mjcf_gravity(path)
    if gravity[0] != 0.0 or gravity[1] != 0.0 or not gravity[2] <= 0.0:
        raise DescriptionError(f"{path}: <option gravity> {gravity.tolist()}: the Delta's hand model takes gravity "
                               "along -z (the generic model, robot.kind: described, takes any)")
    psi = []
    for arm, *_ in LIMB_JOINTS:
        Rm = f.placement(arm).rotation
        psi.append(math.atan2(Rm[1, 0], Rm[0, 0]) % (2 * math.pi))
    try:
        geometry = DeltaGeometry(L1=float(f.placement("elbow1_y").translation[0]),
                                 L2=float(-f.placement("wrist1_n").translation[0]),
                                 R=float(np.linalg.norm(f.placement("q1").translation)),
                                 r=float(np.linalg.norm(f.model.frames[f.model.getFrameId(CENTRE_SITE)]
                                                        .placement.translation)),
                                 psi=(psi[0], psi[1], psi[2]))
    except ValueError as exc:
        raise DescriptionError(f"{path}: not a Delta's geometry: {exc}") from None
    arms, rods, plat = [], [], _platform_frame(geometry, 0).act(f.inertia("wrist1_y"))
    for i, (arm, elbow_y, rod, wrist_n, wrist_y) in enumerate(LIMB_JOINTS):
        m_e, J_e = f.cross(elbow_y)
        m_w, J_w = f.cross(wrist_n)
        arms.append(f.inertia(arm) + f.placement(elbow_y).act(pin.Inertia(m_e, np.zeros(3), np.zeros((3, 3)))))
        spin = (J_e + J_w) * np.diag([1.0, 1.0, 0.0])           # the crosses' turning, on the rod's x and y
        rods.append(_rod_frame(geometry).act(f.inertia(rod) + pin.Inertia(0.0, np.zeros(3), spin)))
        at_P = _platform_frame(geometry, i)
        plat = plat + at_P.act(pin.Inertia(m_w, np.zeros(3), np.zeros((3, 3))))
        if i > 0:
            plat = plat + at_P.act(f.inertia(wrist_y))
    v = np.array([f.model.joints[f.id[arm]].idx_v for arm, *_ in LIMB_JOINTS])
    m = f.model
    pi = np.concatenate([*(_hand(b) for b in (*arms, *rods, plat)), m.damping[v], m.friction[v], m.armature[v]])
    return FastPath(path, geometry, pi.astype(float), gravity=float(-gravity[2]))


def _rod_frame(geometry: DeltaGeometry) -> pin.SE3:
    """The file's rod frame (at ``B_i``) seen from the hand model's (at ``P_i``)."""
    return pin.SE3(_ROD_AXES, np.array([geometry.L2, 0.0, 0.0]))


def _platform_frame(geometry: DeltaGeometry, limb: int) -> pin.SE3:
    """The frame at ``P_i`` with the limb's axes ``Rz(psi_i)`` (the platform's at ``P_1``, a yoke's)
    seen from the hand model's platform frame (at ``p``, world axes)."""
    psi = geometry.psi[limb]
    c, s = math.cos(psi), math.sin(psi)
    return pin.SE3(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), geometry.r * np.array([c, s, 0.0]))


def described_parameters(path: str | Path, hand_parameters, described: DescribedRobot) -> np.ndarray:
    """The generic model's parameter vector (``described.parameter_names``: pinocchio's bodies and the
    drive terms ``fv_q<i>``, ``fc_q<i>``, ``Jm_q<i>``) of hand parameters (79,) of the Delta of the
    file ``path``: the crosses and yokes as the file has them, each arm, rod and the platform the
    hand body less what the file's crosses and yokes add to it (:func:`read_values` inverted).
    """
    path = Path(path)
    f = _Reading(path)
    reading = read_values(path)
    geometry, file_hand = cast(DeltaGeometry, reading.geometry), reading.parameters
    hand = np.asarray(hand_parameters, float)
    bodies: dict[str, np.ndarray] = {}
    for j in range(1, f.model.njoints):
        bodies[f.model.names[j]] = np.asarray(f.model.inertias[j].toDynamicParameters(), float)
    delta_hand = hand - file_hand                             # what the identification moved
    for k, (arm, _, rod, _, _) in enumerate(LIMB_JOINTS):
        bodies[arm] = bodies[arm] + _moved(pin.SE3.Identity(), delta_hand[10 * k:10 * k + 10])
        bodies[rod] = bodies[rod] + _moved(_rod_frame(geometry).inverse(), delta_hand[30 + 10 * k:40 + 10 * k])
    bodies["wrist1_y"] = bodies["wrist1_y"] + _moved(_platform_frame(geometry, 0).inverse(), delta_hand[60:70])
    by_joint = {f.model.names[j]: j for j in range(1, f.model.njoints)}
    parameter_names = described.parameter_names
    out = np.zeros(len(parameter_names))
    drives = {f"{term}_{a}": hand[N_BODY_PARAMS + 3 * t + i]
              for t, term in enumerate(("fv", "fc", "Jm")) for i, a in enumerate(ACTUATOR_NAMES)}
    body_joint = {_body_name(f.model, j): f.model.names[j] for j in by_joint.values()}
    for k, name in enumerate(parameter_names):
        if "." in name:
            body, p = name.rsplit(".", 1)
            out[k] = bodies[body_joint[body]][_PIN_ORDER.index(p)]
        else:
            out[k] = drives[name]
    return out


def _body_name(model, joint: int) -> str:
    for frame in model.frames:
        if frame.parentJoint == joint and frame.type == pin.FrameType.BODY:
            return frame.name
    return model.names[joint]


def described_delta(path: str | Path, geometry: DeltaGeometry, coulomb_width: float = 0.01) -> DescribedRobot:
    """The generic model of a Delta file, actuated ``q1..q3``, its home the hand model's (arms
    horizontal)."""
    b, c = Delta(geometry).rod_angles(np.zeros((1, 3)))
    tree = tree_configuration(np.zeros((1, 3)), b, c)
    return DescribedRobot(path, ACTUATOR_NAMES, home={k: float(v[0]) for k, v in tree.items()},
                          coulomb_width=coulomb_width)


@lru_cache(maxsize=8)
def _fast_path(path: Path, stamp: tuple[int, int], coulomb_width: float) -> FastPath:
    reading = read_values(path)
    geometry, pi, gravity = cast(DeltaGeometry, reading.geometry), reading.parameters, reading.gravity
    described = described_delta(path, geometry, coulomb_width)
    hand = Delta(geometry, coulomb_width=coulomb_width, gravity=gravity)
    rng = np.random.default_rng(0)
    n = FAST_PATH_STATES
    q, qd, qdd = rng.uniform(-0.4, 0.4, (n, 3)), rng.normal(0, 1.5, (n, 3)), rng.normal(0, 10.0, (n, 3))
    try:
        b, c = hand.rod_angles(q)
        tree = tree_configuration(q, b, c)
        guess = np.stack([tree[name] for name in described.joint_names], axis=1)
        tau_hand = hand.identification_regressor(q, qd, qdd)[0] @ pi
        tau_file = described.identification_regressor(q, qd, qdd, guess)[0] @ described.nominal_parameters()
    except (ArithmeticError, ValueError) as exc:
        raise DescriptionError(f"{path}: the Delta read off this file does not move about its home: {exc}") from None
    agreement = check_fast_path(path, "Delta", tau_hand, tau_file)
    return dataclasses.replace(reading, agreement=agreement)


def fast_path(path: str | Path, coulomb_width: float = 0.01) -> FastPath:
    """The Delta of a description file (with its gravity, m/s² along ``-z``): the hand model's
    geometry and parameters read off it (:func:`read_values`), held to the file's generic model
    (torques agree on :data:`~ident_hw.model.fast_path.FAST_PATH_STATES` states). Read once per
    file version (its modification time and size).

    Raises:
        DescriptionError: the file cannot be read as a Delta, or its torques disagree.
    """
    path = Path(path).resolve()
    if not path.is_file():
        raise DescriptionError(f"{path}: no such description file")
    st = path.stat()
    return _fast_path(path, (st.st_mtime_ns, st.st_size), float(coulomb_width))
