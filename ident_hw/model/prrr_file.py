"""The 3PRRR's hand model (:class:`~ident_hw.model.robot.ThreePRRR`) built from its description
file, checked against the file's generic model (:mod:`ident_hw.model.fast_path`).

The file follows the frames of ``configs/robots/3prrr.xml`` (its header): per chain ``i`` a slide
joint ``zeta<i>`` (its body the carriage, the joint frame at ``A_i`` with ``x`` along the guide),
a hinge ``theta<i>`` (link 1, frame at ``A_i`` with world axes at ``theta = 0``, ``x`` along the
link), a hinge ``elbow<i>`` (link 2, frame at ``B_i``); on chain 1 a hinge ``ee_hinge`` (the
end-effector, frame at ``C_1``) with the site ``ee_point`` at the end-effector point. The hand
model's values are read off chain 1 (pinocchio's reading of the file):

- geometry (m, rad): ``a`` and ``gamma_i`` from the placement of ``zeta<i>``, ``l1`` from that of
  ``elbow1``, ``l2`` from that of ``ee_hinge``, ``h`` the distance of ``ee_point`` from it, ``s1``,
  ``s2`` the links' centres of mass along ``x``;
- parameters: ``m_c``, ``m_l1``, ``m_l2``, ``m_ee`` the bodies' masses, ``I_l1``, ``I_l2``,
  ``I_ee`` their inertias about the centre of mass about ``z`` (the planar motion's only
  rotation), ``f_v``, ``f_c`` the actuated joints' MJCF ``damping`` and ``frictionloss``.

What the planar motion never moves (out-of-plane inertia, a carriage's rotational inertia) is
the file's and does not reach the hand model; chains 2 and 3 are the hand model's copies of
chain 1, which the torque check (:func:`~ident_hw.model.fast_path.check_fast_path`) holds.

:func:`described_parameters` goes the other way for identified values (what ``ident-hw export``
writes): each body keeps the file's centre of mass and the shape of its inertia tensor, scaled
to the identified mass and inertia about ``z``.
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import numpy as np

from .described import DescribedRobot, DescriptionError, load_description
from .fast_path import FAST_PATH_STATES, FastPath, check_fast_path
from .parameters import ACTUATOR_NAMES, Geometry, InertialParams
from .robot import ThreePRRR

#: the tree joints of a 3PRRR file by chain (slide, link 1, link 2), and the end-effector's
CHAIN_JOINTS = tuple((f"zeta{i}", f"theta{i}", f"elbow{i}") for i in (1, 2, 3))
EE_JOINT = "ee_hinge"
EE_SITE = "ee_point"


def tree_configuration(X, theta, beta, zeta) -> dict[str, np.ndarray]:
    """Tree joint values by joint name, each (N,), of hand poses: ``zeta_i``, ``theta_i``,
    ``beta_i - theta_i`` per chain, ``alpha - beta_1`` for the end-effector (rad, m)."""
    X, theta, beta, zeta = (np.atleast_2d(np.asarray(v, float)) for v in (X, theta, beta, zeta))
    values = {EE_JOINT: X[:, 2] - beta[:, 0]}
    for i, (slide, link1, link2) in enumerate(CHAIN_JOINTS):
        values[slide], values[link1], values[link2] = zeta[:, i], theta[:, i], beta[:, i] - theta[:, i]
    return values


def described_3prrr(path: str | Path, geometry: Geometry, coulomb_width: float = 1e-3) -> DescribedRobot:
    """The generic model of a 3PRRR file, actuated ``theta1..3, zeta1..3``, its home the hand
    model's (``geometry``: its assembly modes)."""
    hand = ThreePRRR(geometry, coulomb_width)
    home = hand.home_actuated()
    m = hand.motion_from_actuated(home[None], np.zeros((1, 6)), np.zeros((1, 6)), np.zeros((1, 3)))
    tree = tree_configuration(m.X, m.theta, m.beta, m.zeta)
    return DescribedRobot(path, ACTUATOR_NAMES, home={k: float(v[0]) for k, v in tree.items()},
                          coulomb_width=coulomb_width)


def _joint(model, name: str, path: Path) -> int:
    if not model.existJointName(name):
        raise DescriptionError(f"{path}: no joint {name!r}: a 3PRRR file has the joints "
                               f"{[j for c in CHAIN_JOINTS for j in c] + [EE_JOINT]} (configs/robots/3prrr.xml)")
    return model.getJointId(name)


def read_values(path: str | Path, modes=(1, 1, 1)) -> tuple[Geometry, InertialParams]:
    """The hand model's geometry (with the assembly ``modes``) and parameters read off a 3PRRR
    file (the module docstring), unchecked.

    Raises:
        DescriptionError: a joint or the site missing, or values no 3PRRR has, naming the file.
    """
    path = Path(path)
    model = load_description(path).model
    ids = {name: _joint(model, name, path) for chain in CHAIN_JOINTS for name in chain}
    ids[EE_JOINT] = _joint(model, EE_JOINT, path)
    if not model.existFrame(EE_SITE):
        raise DescriptionError(f"{path}: no site {EE_SITE!r} (the end-effector point on the body of {EE_JOINT!r})")
    gamma = []
    for slide, _, _ in CHAIN_JOINTS:
        R = model.jointPlacements[ids[slide]].rotation
        gamma.append(math.atan2(R[1, 0], R[0, 0]) % (2 * math.pi))
    A1 = model.jointPlacements[ids["zeta1"]].translation
    n1 = np.array([-math.sin(gamma[0]), math.cos(gamma[0]), 0.0])
    site = model.frames[model.getFrameId(EE_SITE)]
    inertia = {name: model.inertias[ids[name]] for name in ("zeta1", "theta1", "elbow1", EE_JOINT)}
    try:
        geometry = Geometry(l1=float(model.jointPlacements[ids["elbow1"]].translation[0]),
                            l2=float(model.jointPlacements[ids[EE_JOINT]].translation[0]),
                            s1=float(inertia["theta1"].lever[0]), s2=float(inertia["elbow1"].lever[0]),
                            h=float(np.linalg.norm(site.placement.translation)), a=float(A1 @ n1),
                            gamma=(gamma[0], gamma[1], gamma[2]), modes=(modes[0], modes[1], modes[2]))
    except ValueError as exc:
        raise DescriptionError(f"{path}: not a 3PRRR's geometry: {exc}") from None
    v = np.array([model.joints[ids[name]].idx_v for name in ACTUATOR_NAMES])
    params = InertialParams(
        m_c=float(inertia["zeta1"].mass), m_l1=float(inertia["theta1"].mass),
        I_l1=float(inertia["theta1"].inertia[2, 2]), m_l2=float(inertia["elbow1"].mass),
        I_l2=float(inertia["elbow1"].inertia[2, 2]), m_ee=float(inertia[EE_JOINT].mass),
        I_ee=float(inertia[EE_JOINT].inertia[2, 2]),
        f_v=tuple(float(x) for x in model.damping[v]), f_c=tuple(float(x) for x in model.friction[v]))
    return geometry, params


#: the hand model's (mass, inertia about z) of each chain's bodies and of the end-effector, by joint
_BODY_VALUES = {"zeta": ("m_c", None), "theta": ("m_l1", "I_l1"), "elbow": ("m_l2", "I_l2"), EE_JOINT: ("m_ee", "I_ee")}


def described_parameters(path: str | Path, hand_parameters, described: DescribedRobot) -> np.ndarray:
    """The generic model's parameter vector (``described.parameter_names``) of hand parameters
    (19,) of the 3PRRR of the file ``path``: each body of every chain the file's, its mass and its
    inertia about ``z`` the hand values: the centre of mass stays where the file (the geometry)
    puts it, the tensor about it is the file's scaled to the new ``Izz`` (a carriage's to the new
    mass; a file's tensor without ``Izz``: a thin disc about ``z``, ``diag(I/2, I/2, I)``); the
    drive terms ``fv``, ``fc`` the hand model's, ``Jm`` 0 (it has none).
    """
    import pinocchio as pin

    model = load_description(Path(path)).model
    hand = InertialParams.from_vector(hand_parameters)
    bodies = {}
    for j in range(1, model.njoints):
        name = model.names[j]
        key = EE_JOINT if name == EE_JOINT else name.rstrip("0123456789")
        mass_name, inertia_name = _BODY_VALUES[key]
        old = model.inertias[j]
        mass = getattr(hand, mass_name)
        if inertia_name is None:
            tensor = old.inertia * (mass / old.mass if old.mass > 0 else 0.0)
        else:
            I = getattr(hand, inertia_name)
            tensor = old.inertia * (I / old.inertia[2, 2]) if old.inertia[2, 2] > 0 else np.diag([I / 2, I / 2, I])
        bodies[described.body_names[j - 1]] = pin.Inertia(mass, old.lever, tensor).toDynamicParameters()
    drives = {}
    for k, a in enumerate(ACTUATOR_NAMES):
        drives[f"fv_{a}"], drives[f"fc_{a}"], drives[f"Jm_{a}"] = hand.f_v[k], hand.f_c[k], 0.0
    out = np.zeros(len(described.parameter_names))
    for k, name in enumerate(described.parameter_names):
        if "." in name:
            body, p = name.rsplit(".", 1)
            out[k] = bodies[body][_PIN_ORDER.index(p)]
        else:
            out[k] = drives[name]
    return out


#: pinocchio's order of a body's ten values (:data:`ident_hw.model.described.BODY_PARAMS`)
_PIN_ORDER = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


@lru_cache(maxsize=8)
def _fast_path(path: Path, stamp: tuple[int, int], modes: tuple[int, ...], coulomb_width: float) -> FastPath:
    geometry, params = read_values(path, modes)
    described = described_3prrr(path, geometry, coulomb_width)
    hand = ThreePRRR(geometry, coulomb_width)
    rng = np.random.default_rng(0)
    n = FAST_PATH_STATES
    Theta = hand.home_actuated() + np.concatenate([rng.uniform(-0.05, 0.05, (n, 3)), rng.uniform(-0.03, 0.03, (n, 3))], 1)
    Thetad = np.concatenate([rng.normal(0, 0.5, (n, 3)), rng.normal(0, 0.05, (n, 3))], axis=1)
    Thetadd = np.concatenate([rng.normal(0, 5.0, (n, 3)), rng.normal(0, 0.5, (n, 3))], axis=1)
    pi = params.as_vector()
    try:
        m = hand.motion_from_actuated(Theta, Thetad, Thetadd, np.zeros((n, 3)))
        tree = tree_configuration(m.X, m.theta, m.beta, m.zeta)
        guess = np.stack([tree[name] for name in described.joint_names], axis=1)
        tau_hand = hand.regressor_of(m) @ pi
        tau_file = described.identification_regressor(Theta, Thetad, Thetadd, guess)[0] @ described.nominal_parameters()
    except (ArithmeticError, ValueError) as exc:
        raise DescriptionError(f"{path}: the 3PRRR read off this file does not move about its home: {exc}") from None
    agreement = check_fast_path(path, "3PRRR", tau_hand, tau_file)
    return FastPath(path, geometry, pi, agreement)


def fast_path(path: str | Path, modes=(1, 1, 1), coulomb_width: float = 1e-3) -> FastPath:
    """The 3PRRR of a description file: the hand model's geometry and parameters read off it
    (:func:`read_values`), held to the file's generic model: the torques of both agree on
    :data:`~ident_hw.model.fast_path.FAST_PATH_STATES` states about home. Read once per file
    version (its modification time and size).

    Raises:
        DescriptionError: the file cannot be read as a 3PRRR, or its torques disagree.
    """
    path = Path(path).resolve()
    if not path.is_file():
        raise DescriptionError(f"{path}: no such description file")
    st = path.stat()
    return _fast_path(path, (st.st_mtime_ns, st.st_size), tuple(int(m) for m in modes), float(coulomb_width))
