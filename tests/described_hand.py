"""The hand-derived robot models seen through the MJCF descriptions of ``configs/robots/``.

For ``tests/test_described_hand.py``: the linear map from a hand model's parameters to the
parameter vector of the generic (MJCF, pinocchio) model, the tree configuration of a hand pose,
and the tree velocities that the hand kinematics give. Written from the frames the XML files
document, independently of ``ident_hw.model.described``.

Body parameters follow pinocchio's dynamic-parameter order (``pin.Inertia.toDynamicParameters``):
mass, first moment ``m c`` and inertia about the joint frame's origin, in the joint frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ident_hw.model.delta import BODY_PARAMS as DELTA_BODY_PARAMS
from ident_hw.model.delta import Delta, DeltaGeometry
from ident_hw.model.parameters import ACTUATOR_NAMES as PRRR_ACTUATORS
from ident_hw.model.parameters import Geometry, InertialParams

ROBOTS = Path(__file__).resolve().parents[1] / "configs" / "robots"
PRRR_XML = ROBOTS / "3prrr.xml"
DELTA_XML = ROBOTS / "delta.xml"

#: pinocchio's order of a body's ten parameters
PIN_PARAMS = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")

# -- the 3PRRR ---------------------------------------------------------------------------------
#: tree joints of 3prrr.xml, in pinocchio's order (depth first, as written)
PRRR_JOINTS = ("zeta1", "theta1", "elbow1", "ee_hinge", "zeta2", "theta2", "elbow2", "zeta3", "theta3", "elbow3")
PRRR_BODIES = ("carriage1", "link1_1", "link2_1", "ee", "carriage2", "link1_2", "link2_2",
               "carriage3", "link1_3", "link2_3")
PRRR_EE_BODY = "ee"
PRRR_EE_SITE = "ee_point"


def pin_body(mass: float, first_moment, inertia) -> np.ndarray:
    """(10,) in :data:`PIN_PARAMS` order from ``m``, ``h = m c`` (3,) and the 3x3 tensor about the origin."""
    I = np.asarray(inertia, float)
    return np.array([mass, *np.asarray(first_moment, float), I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]])


def from_centre(mass: float, com, inertia_at_com) -> np.ndarray:
    """(10,) of a body of mass ``mass`` with centre of mass ``com`` and tensor ``inertia_at_com``
    (3x3, about the centre of mass): parallel axis to the origin (linear in ``mass`` and the tensor
    for a fixed ``com``)."""
    c = np.asarray(com, float)
    return pin_body(mass, mass * c, np.asarray(inertia_at_com, float) + mass * (c @ c * np.eye(3) - np.outer(c, c)))


def moved(mass: float, h, inertia, rotation, origin) -> np.ndarray:
    """(10,) of a body given about another frame: ``h``, ``inertia`` (3x3) about the old origin in the
    old axes; ``rotation`` maps old-axes coordinates to new-axes ones; ``origin`` is the old origin in
    the new frame. Linear in ``(mass, h, inertia)``:
    ``I_new = I + m(|d|^2 1 - d d^T) - 2 (h.d) 1 + h d^T + d h^T``, ``d`` = new origin - old origin."""
    R = np.asarray(rotation, float)
    h = R @ np.asarray(h, float)
    I = R @ np.asarray(inertia, float) @ R.T
    d = -np.asarray(origin, float)
    I_new = I + mass * (d @ d * np.eye(3) - np.outer(d, d)) - 2 * (h @ d) * np.eye(3) + np.outer(h, d) + np.outer(d, h)
    return pin_body(mass, h + mass * np.asarray(origin, float), I_new)


def prrr_bodies(params: InertialParams, geometry: Geometry) -> dict[str, np.ndarray]:
    """Each body of 3prrr.xml (10,) from the hand parameters: carriage a point mass, links slender
    rods (tensor at the centre of mass ``diag(0, I, I)``), end-effector a thin disc (``diag(I/2, I/2, I)``)
    whose centre is the end-effector point, ``-h n(gamma_1)`` in the frame at ``C_1``."""
    g, p = geometry, params
    rod = lambda inertia: np.diag([0.0, inertia, inertia])  # noqa: E731
    g1 = g.gamma[0]
    out = {}
    for i in (1, 2, 3):
        out[f"carriage{i}"] = pin_body(p.m_c, np.zeros(3), np.zeros((3, 3)))
        out[f"link1_{i}"] = from_centre(p.m_l1, (g.s1, 0, 0), rod(p.I_l1))
        out[f"link2_{i}"] = from_centre(p.m_l2, (g.s2, 0, 0), rod(p.I_l2))
    out["ee"] = from_centre(p.m_ee, (g.h * np.sin(g1), -g.h * np.cos(g1), 0), np.diag([p.I_ee / 2, p.I_ee / 2, p.I_ee]))
    return out


def prrr_drives(params: InertialParams) -> dict[str, float]:
    """``fv_<a>``, ``fc_<a>`` of the hand model per actuator name; ``Jm_<a>`` 0 (the hand model has none)."""
    out = {}
    for k, a in enumerate(PRRR_ACTUATORS):
        out[f"fv_{a}"] = params.f_v[k]
        out[f"fc_{a}"] = params.f_c[k]
        out[f"Jm_{a}"] = 0.0
    return out


def described_vector(bodies: dict[str, np.ndarray], drives: dict[str, float], parameter_names) -> np.ndarray:
    """The vector in the order of ``parameter_names`` (``body.p``, ``fv_a``, ``fc_a``, ``Jm_a``);
    bodies the hand model does not have are 0. An unknown name is an error."""
    out = np.zeros(len(parameter_names))
    for k, name in enumerate(parameter_names):
        if "." in name:
            body, p = name.rsplit(".", 1)
            out[k] = bodies[body][PIN_PARAMS.index(p)] if body in bodies else 0.0
        elif name in drives:
            out[k] = drives[name]
        else:
            raise KeyError(f"parameter {name!r} is neither a body parameter nor a drive term")
    return out


def prrr_map(pi_hand, geometry: Geometry, parameter_names) -> np.ndarray:
    """The described parameter vector of the hand vector ``pi_hand`` (19,) (``InertialParams.NAMES``)."""
    params = InertialParams.from_vector(pi_hand)
    return described_vector(prrr_bodies(params, geometry), prrr_drives(params), parameter_names)


def linear_map(function, n_in: int) -> np.ndarray:
    """The matrix (n_out, n_in) of a linear ``function`` of a vector (n_in,)."""
    return np.stack([function(e) for e in np.eye(n_in)], axis=1)


def prrr_tree(X, theta, beta, zeta) -> np.ndarray:
    """Tree configurations (N, 10) of 3prrr.xml (order :data:`PRRR_JOINTS`) of hand poses."""
    X, theta, beta, zeta = (np.atleast_2d(v) for v in (X, theta, beta, zeta))
    cols = [zeta[:, 0], theta[:, 0], beta[:, 0] - theta[:, 0], X[:, 2] - beta[:, 0]]
    for i in (1, 2):
        cols += [zeta[:, i], theta[:, i], beta[:, i] - theta[:, i]]
    return np.stack(cols, axis=1)


def prrr_tree_motion(motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tree ``q``, ``v``, ``a`` (N, 10) of a hand :class:`~ident_hw.model.kinematics.Motion`."""
    m = motion
    return (prrr_tree(m.X, m.theta, m.beta, m.zeta), prrr_tree(m.Xd, m.thetad, m.betad, m.zetad),
            prrr_tree(m.Xdd, m.thetadd, m.betadd, m.zetadd))


# -- the Delta ---------------------------------------------------------------------------------
DELTA_JOINTS = tuple(name for i in (1, 2, 3) for name in (f"q{i}", f"elbow{i}_y", f"elbow{i}_n", f"wrist{i}_n", f"wrist{i}_y"))
DELTA_BODIES = ("arm1", "elbow1", "rod1", "wrist1", "platform", "arm2", "elbow2", "rod2", "wrist2", "end2",
                "arm3", "elbow3", "rod3", "wrist3", "end3")
DELTA_PLATFORM_BODY = "platform"
DELTA_CENTRE_SITE = "plat_centre"
#: rod axes of the hand model (x = u, y = -n) seen from the rod frame of delta.xml (x = u, z = n): Rx(-pi/2)
_ROD_ROTATION = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])


def hand_tensor(six) -> np.ndarray:
    """3x3 from the hand model's ``[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]``."""
    xx, xy, xz, yy, yz, zz = six
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def delta_bodies(pi_hand, geometry: DeltaGeometry) -> dict[str, np.ndarray]:
    """Each body of delta.xml (10,) from the hand vector (79,): the arms in the same frame; a rod
    from its hand frame at ``P_i`` to the frame at ``B_i`` (rotation ``Rx(-pi/2)``, ``P_i`` at
    ``(-L2, 0, 0)``); the platform from ``p`` (world axes) to ``P_1 = p + r e_1``; crosses and
    the welded end bodies 0."""
    pi = np.asarray(pi_hand, float)
    psi1 = geometry.psi[0]
    out = {}
    for k, body in enumerate(("arm1", "arm2", "arm3", "rod1", "rod2", "rod3", "plat")):
        b = dict(zip(DELTA_BODY_PARAMS, pi[10 * k:10 * k + 10]))
        m, h = b["m"], np.array([b["mx"], b["my"], b["mz"]])
        I = hand_tensor([b[p] for p in ("Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")])
        if body.startswith("arm"):
            out[body] = pin_body(m, h, I)
        elif body.startswith("rod"):
            out[body] = moved(m, h, I, _ROD_ROTATION, (-geometry.L2, 0.0, 0.0))
        else:
            out["platform"] = moved(m, h, I, np.eye(3), -geometry.r * np.array([np.cos(psi1), np.sin(psi1), 0.0]))
    return out


def delta_drives(pi_hand, actuator_names=("q1", "q2", "q3")) -> dict[str, float]:
    """``fv_<a>``, ``fc_<a>``, ``Jm_<a>`` of the hand vector per actuator name."""
    pi = np.asarray(pi_hand, float)
    out = {}
    for i, a in enumerate(actuator_names):
        out[f"fv_{a}"], out[f"fc_{a}"], out[f"Jm_{a}"] = pi[70 + i], pi[73 + i], pi[76 + i]
    return out


def delta_map(pi_hand, geometry: DeltaGeometry, parameter_names) -> np.ndarray:
    """The described parameter vector of the hand vector ``pi_hand`` (79,)."""
    return described_vector(delta_bodies(pi_hand, geometry), delta_drives(pi_hand), parameter_names)


def delta_rod_rates(delta: Delta, q, qd, qdd):
    """Rod angles ``b``, ``c`` and their rates and accelerations (each (N, 3)) from the hand model's
    bodies: ``omega = bd y_i + cd n_i``, ``alpha = bdd y_i + cdd n_i + bd cd (y_i x n_i)`` with
    ``y_i``, ``n_i``, ``y_i x n_i`` orthonormal."""
    q = np.atleast_2d(q)
    b, c = delta.rod_angles(q)
    bodies = delta.bodies(q, qd, qdd)
    psi = np.asarray(delta.geometry.psi)
    y = np.stack([-np.sin(psi), np.cos(psi), np.zeros(3)], axis=1)                         # (3, 3)
    nvec = (np.sin(b)[..., None] * np.stack([np.cos(psi), np.sin(psi), np.zeros(3)], axis=1)
            + np.cos(b)[..., None] * np.array([0, 0, 1.0]))                                 # (N, 3, 3)
    omega, alpha = np.swapaxes(bodies.omega[3:6], 0, 1), np.swapaxes(bodies.alpha[3:6], 0, 1)  # (N, 3, 3)
    bd, cd = np.einsum("nlk,lk->nl", omega, y), np.einsum("nlk,nlk->nl", omega, nvec)
    bdd, cdd = np.einsum("nlk,lk->nl", alpha, y), np.einsum("nlk,nlk->nl", alpha, nvec)
    return (b, c), (bd, cd), (bdd, cdd)


def delta_tree(q, b, c) -> np.ndarray:
    """Tree configurations (or rates) (N, 15) of delta.xml (order :data:`DELTA_JOINTS`)."""
    q, b, c = (np.atleast_2d(v) for v in (q, b, c))
    cols = []
    for i in range(3):
        cols += [q[:, i], b[:, i] - q[:, i], c[:, i], -c[:, i], -b[:, i]]
    return np.stack(cols, axis=1)


def delta_tree_motion(delta: Delta, q, qd, qdd):
    """Tree ``q``, ``v``, ``a`` (N, 15) of an arm motion, from the hand kinematics."""
    (b, c), (bd, cd), (bdd, cdd) = delta_rod_rates(delta, q, qd, qdd)
    return delta_tree(q, b, c), delta_tree(qd, bd, cd), delta_tree(qdd, bdd, cdd)


# -- an exported hand robot ----------------------------------------------------------------------
def export_for_mujoco(results: Path, exported: Path) -> dict[str, float]:
    """``ident-hw export RESULTS --to EXPORTED --for-mujoco`` (which must succeed); the
    consistent values of the results folder's ``parameters.json`` by name."""
    import json

    from cli_runs import ident_hw      # in this process: the export's imports are the test's already

    done = ident_hw("export", results, "--to", exported, "--for-mujoco")
    assert done.returncode == 0, done.stderr
    consistent = json.loads((results / "parameters.json").read_text())["consistent"]
    return {p["name"]: p["value"] for p in consistent["parameters"]}


def torques_agree(tau, tau_reference, tolerance: float = 1e-9) -> None:
    """Each actuator's largest difference over the states within ``tolerance`` of its largest torque."""
    error = np.abs(tau - tau_reference).max(axis=0) / np.abs(tau_reference).max(axis=0)
    assert error.max() < tolerance, error


def mujoco_loads(path: Path, bodies: int) -> None:
    """MuJoCo (where installed) loads ``path``: the world and every body of the file."""
    import pytest

    mujoco = pytest.importorskip("mujoco")
    assert mujoco.MjModel.from_xml_path(str(path)).nbody >= bodies + 1
