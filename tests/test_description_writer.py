"""Identified parameters written into a description file (:mod:`ident_hw.experiment.description_writer`).

Checked against computations independent of the writer:

- the written ``<inertial>`` of each moving body is the body drawn here in its own frame (the
  random bodies are drawn as mass, centre of mass and inertia about it in the body frame, and
  turned into the parameter vector here: frame change and parallel axis theorem by hand);
- round trip on the four shipped descriptions (2R URDF, Stewart, 3PRRR and Delta MJCF): a
  :class:`~ident_hw.model.described.DescribedRobot` of the written file gives the written vector
  back as its nominal parameters (random physical values on all four; the description's own
  values, massless crosses and point masses included, on the three whose bodies are physical;
  drive terms throughout; URDF: Jm lives in a comment, read by no parser);
- MuJoCo, a second reader of the same files: its inverse dynamics of the open tree (``mj_inverse``,
  closures and friction loss disabled) is the parameter vector's ``Y(q, v, a) pi`` of the source
  tree (pinocchio's regressor) plus the written armature and damping, at random tree states; its
  compiler refuses a body of the shipped nominal values that ``for_mujoco=True`` refuses too;
- a small MJCF written here with what the shipped files do not have: a joint away from its body's
  origin, rotated bodies, an unaligned hinge, a body merged into its parent that has geometry, a
  default class with joint damping, compiler options that would override the inertials;
- the plant of a written file counts its rotor inertia once (pinocchio's crba adds armature);
- bad input: another format's suffix, a vector of the wrong length, unphysical bodies (the Delta's
  test-vector arm among them), negative drive terms; a solver's rounding below the physical set
  projected onto it.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import described_hand as dh
from ident_hw.config import load_config
from ident_hw.config.robots import model_of
from ident_hw.model import Delta, ThreePRRR
from ident_hw.model.delta import DeltaGeometry, nominal_parameters
from ident_hw.model.described import DescribedRobot, DescriptionError, MasslessBodyWarning, load_description
from ident_hw.experiment.description_writer import write_description
from ident_hw.model.parameters import ACTUATOR_NAMES as PRRR_ACTUATORS

ROBOTS = dh.ROBOTS
ROUND_TRIP = 1e-12      # relative to each body's largest value
TORQUE_TOL = 1e-9       # relative agreement with MuJoCo
LEGS = tuple(f"leg{i}" for i in range(1, 7))


# ------------------------------------------------------------------------------ the robots
def _prrr_home() -> dict[str, float]:
    cfg = load_config(ROBOTS.parent / "robot-3prrr.yaml").robot
    hand = ThreePRRR(model_of(cfg).geometry)
    X0 = np.zeros((1, 3))
    theta, beta = hand.inverse_kinematics(X0, X0)
    return dict(zip(dh.PRRR_JOINTS, dh.prrr_tree(X0, theta, beta, X0)[0]))


def _delta_home() -> dict[str, float]:
    q0 = np.zeros((1, 3))
    return dict(zip(dh.DELTA_JOINTS, dh.delta_tree_motion(Delta(DeltaGeometry()), q0, q0, q0)[0][0]))


SOURCES = {
    "2r": lambda: DescribedRobot(ROBOTS / "2r.urdf", ("joint1", "joint2"), actuator_names=("shoulder", "elbow")),
    "stewart": lambda: DescribedRobot(ROBOTS / "stewart.xml", LEGS),
    "3prrr": lambda: DescribedRobot(ROBOTS / "3prrr.xml", PRRR_ACTUATORS, home=_prrr_home()),
    "delta": lambda: DescribedRobot(ROBOTS / "delta.xml", ("q1", "q2", "q3"), home=_delta_home()),
}


@pytest.fixture(scope="module")
def robots() -> dict[str, DescribedRobot]:
    return {name: make() for name, make in SOURCES.items()}


def _home(robot: DescribedRobot) -> dict[str, float]:
    """The source's home tree configuration by joint name (an assembled guess for the copy)."""
    q = robot.pose(robot.home_actuated(), None)
    return {name: float(q[robot.model.joints[j].idx_q]) for j, name in enumerate(robot.model.names) if j > 0}


def _reload(robot: DescribedRobot, path: Path) -> DescribedRobot:
    return DescribedRobot(path, robot.actuated_joints, actuator_names=robot.actuator_names, home=_home(robot),
                          home_actuated=robot.home_actuated())


# ------------------------------------------------------------------------------ parameters by hand
def _placement(robot: DescribedRobot, j: int) -> tuple[np.ndarray, np.ndarray]:
    """``(R, t)`` of joint ``j``'s body frame in its joint frame: ``x_joint = R x_body + t``."""
    for frame in robot.model.frames:
        if frame.type == pin.FrameType.BODY and frame.parentJoint == j:
            return frame.placement.rotation, frame.placement.translation
    raise AssertionError(f"no body on joint {j}")


def _about_joint(m: float, c_body, I_body, R, t) -> np.ndarray:
    """pinocchio's ten values (m, m c, inertia about the joint origin; joint frame) of a body of
    mass ``m``, centre of mass ``c_body`` and inertia ``I_body`` about it (body frame)."""
    c = R @ np.asarray(c_body) + t
    I = R @ I_body @ R.T + m * (c @ c * np.eye(3) - np.outer(c, c))
    return np.array([m, *(m * c), I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]])


def _random_body(rng, mass: float, size: float):
    """Mass, centre of mass, inertia about it of a physical body (a positive mass distribution:
    positive second moments along random principal axes; triangle inequality strict)."""
    m = mass * rng.uniform(0.8, 1.25)
    second = m * (size * rng.uniform(0.2, 1.0, 3)) ** 2
    principal = np.array([second[1] + second[2], second[0] + second[2], second[0] + second[1]])
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return m, size * rng.uniform(-1, 1, 3), Q @ np.diag(principal) @ Q.T


def _random_params(robot: DescribedRobot, rng) -> tuple[np.ndarray, list]:
    """A physical parameter vector about the nominal one (masses scaled, every body given a mass
    and an inertia, centres of mass moved) and the bodies drawn, in their own frames."""
    pi = robot.nominal_parameters()
    bodies = []
    for j in range(1, robot.model.njoints):
        nominal_mass = pi[10 * (j - 1)]
        body = _random_body(rng, max(nominal_mass, 0.05), 0.1)
        bodies.append(body)
        pi[10 * (j - 1):10 * j] = _about_joint(*body, *_placement(robot, j))
    n = len(robot.actuated_joints)
    pi[len(pi) - 3 * n:] = rng.uniform(0.01, 2.0, 3 * n)
    return pi, bodies


def _with_drives(robot: DescribedRobot, rng) -> np.ndarray:
    """The nominal vector (massless bodies, point masses, the Delta's test-vector arm) with drive terms."""
    pi = robot.nominal_parameters()
    n = len(robot.actuated_joints)
    pi[len(pi) - 3 * n:] = rng.uniform(0.01, 2.0, 3 * n)
    return pi


def _assert_bodies_close(got, want, robot, what=""):
    for j in range(len(robot.body_names)):
        g, w = got[10 * j:10 * j + 10], want[10 * j:10 * j + 10]
        scale = max(np.abs(w).max(), 1e-300)
        assert np.abs(g - w).max() <= ROUND_TRIP * scale, (what, robot.body_names[j], g, w)


def _jm_comments(path: Path) -> dict[str, float]:
    """Jm per joint from the written URDF's comments (the writer's format, read here)."""
    root = ET.parse(path, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))).getroot()
    out = {}
    for joint in root.findall("joint"):
        for child in joint:
            if child.tag is ET.Comment and child.text.strip().startswith("ident_hw: Jm = "):
                out[joint.get("name")] = float(child.text.split("=")[1].split()[0])
    return out


# ------------------------------------------------------------------------------ round trips
@pytest.mark.parametrize("name, kind", [(name, "random") for name in SOURCES]
                         + [(name, "nominal") for name in ("2r", "stewart", "3prrr", "delta")])
def test_round_trip(robots, name, kind, tmp_path):
    robot = robots[name]
    rng = np.random.default_rng([list(SOURCES).index(name), len(kind)])
    pi = _with_drives(robot, rng) if kind == "nominal" else _random_params(robot, rng)[0]
    to = tmp_path / "copy" / robot.path.name
    assert write_description(robot, pi, to) == to
    text = to.read_text(encoding="utf-8")
    assert text.count("Written by ident_hw from identified parameters") == 1
    assert str(tmp_path) not in text and str(ROBOTS) not in text and "/" not in text.split("-->")[0]
    assert not list(to.parent.glob(".*"))                      # no temporary file left behind

    copy = _reload(robot, to)
    assert copy.parameter_names == robot.parameter_names
    got = copy.nominal_parameters()
    n = len(robot.actuated_joints)
    b = len(pi) - 3 * n
    _assert_bodies_close(got[:b], pi[:b], robot, kind)
    if robot.path.suffix == ".urdf":
        np.testing.assert_allclose(got[b:b + 2 * n], pi[b:b + 2 * n], rtol=ROUND_TRIP)
        assert np.all(got[b + 2 * n:] == 0.0)                  # no URDF parser reads a rotor inertia...
        jm = _jm_comments(to)                                  # ...it is in a comment per joint
        assert [jm[j] for j in robot.actuated_joints] == pi[b + 2 * n:].tolist()
    else:
        np.testing.assert_allclose(got[b:], pi[b:], rtol=ROUND_TRIP)
        np.testing.assert_array_equal(copy.drive_parameters(), got[b:])

    # the same inputs give the same bytes; writing the copy again changes nothing
    again = tmp_path / "again" / robot.path.name
    write_description(robot, pi, again)
    assert again.read_bytes() == to.read_bytes()
    third = tmp_path / "third" / robot.path.name
    write_description(copy, pi, third)
    assert third.read_bytes() == to.read_bytes()


def test_written_inertials_are_the_bodies_drawn(robots, tmp_path):
    """The random bodies, drawn in their own frames, are what the file says (Stewart: rotated
    platform inertial in the source; 3PRRR: bodies rotated by the guide angles)."""
    for name in ("stewart", "3prrr", "2r"):
        robot = robots[name]
        pi, bodies = _random_params(robot, np.random.default_rng(3))
        to = write_description(robot, pi, tmp_path / robot.path.name)
        root = ET.parse(to).getroot()
        for j, (m, c, I) in enumerate(bodies, start=1):
            body = robot.body_names[j - 1]
            if to.suffix == ".urdf":
                inertial = root.find(f"link[@name='{body}']/inertial")
                origin, inertia = inertial.find("origin"), inertial.find("inertia").attrib
                assert origin.get("rpy") == "0 0 0"
                pos = [float(x) for x in origin.get("xyz").split()]
                mass = float(inertial.find("mass").get("value"))
                six = [float(inertia[k]) for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")]
            else:
                inertial = next(el for el in root.iter("body") if el.get("name") == body).find("inertial")
                assert set(inertial.attrib) == {"pos", "mass", "fullinertia"}
                pos = [float(x) for x in inertial.get("pos").split()]
                mass = float(inertial.get("mass"))
                six = [float(x) for x in inertial.get("fullinertia").split()]
            scale = np.abs(I).max()
            assert mass == pytest.approx(m, rel=1e-14)
            np.testing.assert_allclose(pos, c, rtol=0, atol=1e-14 * max(1.0, np.abs(c).max()))
            np.testing.assert_allclose(six, [I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]],
                                       rtol=0, atol=1e-12 * scale)


def test_what_else_the_file_says_is_kept(robots, tmp_path):
    """Closures, sites, limits, passive joints, comments and the fixed tool link are the source's."""
    robot = robots["stewart"]
    pi, _ = _random_params(robot, np.random.default_rng(5))
    text = write_description(robot, pi, tmp_path / "stewart.xml").read_text(encoding="utf-8")
    source = robot.path.read_text(encoding="utf-8")
    for line in source.splitlines():
        if "<inertial" in line or any(f'name="{leg}"' in line for leg in LEGS):
            continue
        if "<body" in line and any(f'name="{b}"' in line for b in ("leg1_cross", "sph_a", "sph_b")):
            continue
        assert line in text, line                   # every other line verbatim (comments, sites, closures)
    passive = [el for el in ET.fromstring(text).iter("joint") if el.get("name") not in LEGS]
    assert passive and all(not {"damping", "frictionloss", "armature"} & set(el.attrib) for el in passive)

    robot = robots["2r"]
    pi, _ = _random_params(robot, np.random.default_rng(6))
    to = write_description(robot, pi, tmp_path / "2r.urdf")
    text = to.read_text(encoding="utf-8")
    assert text.startswith('<?xml version="1.0"?>\n<!--\n  Written by ident_hw')
    assert "Planar 2R direct-drive arm" in text                   # the source's own header kept
    assert '<link name="tool"/>' in text
    assert '<limit lower="-3.1416" upper="3.1416" effort="100" velocity="10"/>' in text
    root = ET.fromstring(text)
    for joint, k in (("joint1", 0), ("joint2", 1)):
        dynamics = root.find(f"joint[@name='{joint}']/dynamics").attrib
        assert float(dynamics["damping"]) == pi[20 + k] and float(dynamics["friction"]) == pi[22 + k]


# ------------------------------------------------------------------------------ MuJoCo
def _mujoco_torques(mj, mjm, model, q, v, a):
    """``mj_inverse`` of the open tree (equality, limits and friction loss off) at pinocchio's
    ``q, v, a``, in pinocchio's joint order."""
    d = mj.MjData(mjm)
    for j in range(1, model.njoints):
        joint = mjm.joint(model.names[j])
        iq, iv = model.joints[j].idx_q, model.joints[j].idx_v
        d.qpos[mjm.jnt_qposadr[joint.id]] = q[iq]
        d.qvel[mjm.jnt_dofadr[joint.id]] = v[iv]
        d.qacc[mjm.jnt_dofadr[joint.id]] = a[iv]
    mj.mj_inverse(mjm, d)
    return np.array([d.qfrc_inverse[mjm.jnt_dofadr[mjm.joint(model.names[j]).id]] for j in range(1, model.njoints)])


def _check_with_mujoco(mj, robot, pi, path, rng, armature=True):
    """MuJoCo's inverse dynamics of the written file = ``Y pi`` of the source tree + the drive terms."""
    mjm = mj.MjModel.from_xml_path(str(path))
    mjm.opt.disableflags |= mj.mjtDisableBit.mjDSBL_CONSTRAINT
    model, data = robot.model, robot.model.createData()
    # pinocchio's MJCF parser does not read <option gravity>: these files give MuJoCo's default
    assert np.array_equal(mjm.opt.gravity, model.gravity.linear)
    n = len(robot.actuated_joints)
    b = len(pi) - 3 * n
    fv, fc, Jm = pi[b:b + n], pi[b + n:b + 2 * n], pi[b + 2 * n:]
    act = [model.joints[model.getJointId(joint)].idx_v for joint in robot.actuated_joints]
    dof = [mjm.jnt_dofadr[mjm.joint(joint).id] for joint in robot.actuated_joints]
    np.testing.assert_allclose(mjm.dof_damping[dof], fv, rtol=1e-15)
    np.testing.assert_allclose(mjm.dof_frictionloss[dof], fc, rtol=1e-15)
    np.testing.assert_allclose(mjm.dof_armature[dof], Jm if armature else 0.0, rtol=1e-15)
    masses = {mjm.body(k).name: mjm.body_mass[k] for k in range(mjm.nbody)}
    for j, body in enumerate(robot.body_names):
        assert masses[body] == pytest.approx(pi[10 * j], rel=1e-14)
    worst = 0.0
    for _ in range(4):
        q, v, a = (rng.uniform(-0.5, 0.5, model.nv) for _ in range(3))
        expected = pin.computeJointTorqueRegressor(model, data, q, v, a) @ pi[:b]
        expected[act] += fv * v[act] + (Jm * a[act] if armature else 0.0)
        got = _mujoco_torques(mj, mjm, model, q, v, a)
        worst = max(worst, np.abs(got - expected).max() / np.abs(expected).max())
    assert worst < TORQUE_TOL, worst


@pytest.mark.parametrize("name", list(SOURCES))
def test_mujoco_reads_the_same_dynamics(robots, name, tmp_path):
    mj = pytest.importorskip("mujoco")
    robot = robots[name]
    rng = np.random.default_rng(11)
    pi, _ = _random_params(robot, rng)
    path = write_description(robot, pi, tmp_path / robot.path.name, for_mujoco=True)
    # URDF: MuJoCo's import reads <dynamics damping friction>, no rotor inertia (neither does pinocchio)
    _check_with_mujoco(mj, robot, pi, path, rng, armature=path.suffix != ".urdf")


def test_for_mujoco_refuses_what_mujoco_refuses(robots, tmp_path):
    """A point-mass carriage (the 3PRRR's first carriage without its rotational inertia, which the
    planar motion never moves) is written for pinocchio; MuJoCo refuses the file, naming a body
    (the first it meets) that ``for_mujoco`` names too. Every shipped file's nominal export loads."""
    mj = pytest.importorskip("mujoco")
    robot = robots["3prrr"]
    pi = robot.nominal_parameters()
    j = robot.body_names.index("carriage1")
    pi[10 * j + 4:10 * j + 10] = 0.0
    path = write_description(robot, pi, tmp_path / robot.path.name)
    with pytest.raises(ValueError, match=r"Element name '(\w+)'") as refused:
        mj.MjModel.from_xml_path(str(path))
    body = re.search(r"Element name '(\w+)'", str(refused.value)).group(1)
    assert body == "carriage1"
    with pytest.raises(DescriptionError, match=rf"(?m)^  {body}: ") as ours:
        write_description(robot, pi, tmp_path / "checked" / robot.path.name, for_mujoco=True)
    assert "MuJoCo would refuse" in str(ours.value)
    assert not (tmp_path / "checked").exists()
    for name, shipped in robots.items():
        mj.MjModel.from_xml_path(str(write_description(shipped, shipped.nominal_parameters(),
                                                       tmp_path / "nominal" / shipped.path.name, for_mujoco=True)))


OFFSETS = """<mujoco model="offsets">
  <!-- a robot with what the shipped files do not have -->
  <compiler angle="radian" boundmass="0.001" boundinertia="1e-6" inertiafromgeom="true"/>
  <default>
    <joint damping="0.5" armature="0.01"/>
  </default>
  <worldbody>
    <body name="base">
      <geom type="box" size="0.1 0.1 0.1"/>
      <body name="arm" pos="0.1 0 0.05" quat="0.9 0.1 0.2 0.3">
        <joint name="j1" type="hinge" axis="0 0.6 0.8" pos="0.05 0.02 0.01"/>
        <geom type="box" size="0.2 0.02 0.02" pos="0.2 0 0"/>
        <body name="tool" pos="0.4 0 0" euler="0.1 0.2 0.3">
          <geom type="sphere" size="0.03"/>
        </body>
        <body name="forearm" pos="0.4 0 0" euler="0.3 -0.2 0.1">
          <joint name="j2" type="slide" axis="1 0 0" pos="0 0.01 0"/>
          <inertial pos="0.1 0 0" mass="0.7" diaginertia="0.002 0.003 0.004"/>
          <body name="hand" pos="0.2 0 0">
            <joint name="j3" type="hinge" axis="0 0 1" pos="0.03 0 0"/>
            <inertial pos="0.05 0 0" mass="0.2" diaginertia="1e-3 1e-3 1e-3"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_joint_offsets_merged_bodies_and_overriding_options(tmp_path):
    source = tmp_path / "offsets.xml"
    source.write_text(OFFSETS)
    with pytest.warns(MasslessBodyWarning, match=r"offsets\.xml: moving bodies without mass: forearm, hand "):
        robot = DescribedRobot(source, ("j1", "j2", "j3"))
    assert robot.body_names == ("arm", "forearm", "hand")
    rng = np.random.default_rng(2)
    # a joint at pos p in its body: the joint frame is the body's, moved by p (MJCF semantics)
    offsets = {"arm": np.array([0.05, 0.02, 0.01]), "forearm": np.array([0, 0.01, 0]), "hand": np.array([0.03, 0, 0])}
    pi = np.zeros(len(robot.parameter_names))
    bodies = []
    for j, body in enumerate(robot.body_names):
        m, c, I = _random_body(rng, 1.0, 0.1)
        bodies.append((m, c, I))
        pi[10 * j:10 * j + 10] = _about_joint(m, c, I, np.eye(3), -offsets[body])
    pi[30:] = rng.uniform(0.01, 1.0, 9)
    to = write_description(robot, pi, tmp_path / "out" / "offsets.xml", for_mujoco=True)
    text = to.read_text()
    assert re.search(r'Compiler options dropped \(they would override the identified inertias\): boundmass="0.001",'
                     r'\s+boundinertia="1e-6", inertiafromgeom="true"\.', text)
    assert '<compiler angle="radian"/>' in text and "<!-- a robot with what the shipped files do not have -->" in text
    root = ET.fromstring(text)
    named = {el.get("name"): el for el in root.iter("body")}
    assert named["tool"].find("inertial").attrib == {"pos": "0 0 0", "mass": "0", "diaginertia": "0 0 0"}
    assert named["base"].find("inertial") is None                # fixed to the world: as it was
    for (m, c, I), body in zip(bodies, robot.body_names):
        inertial = named[body].find("inertial")
        np.testing.assert_allclose([float(x) for x in inertial.get("pos").split()], c, rtol=0, atol=1e-15)
        np.testing.assert_allclose([float(x) for x in inertial.get("fullinertia").split()],
                                   [I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]], rtol=0,
                                   atol=1e-13 * np.abs(I).max())
    copy = DescribedRobot(to, ("j1", "j2", "j3"))
    _assert_bodies_close(copy.nominal_parameters()[:30], pi[:30], robot)
    np.testing.assert_allclose(copy.drive_parameters(), pi[30:], rtol=1e-15)   # the class default overridden

    mj = pytest.importorskip("mujoco")
    _check_with_mujoco(mj, robot, pi, to, rng)


def test_the_plant_counts_the_written_rotor_inertia_once(robots, tmp_path):
    """pinocchio's crba and rnea add a file's armature: the copy's plant, fed the same vector,
    is the source's (the rotor inertia comes from the vector's Jm, not twice)."""
    robot = robots["stewart"]
    pi, _ = _random_params(robot, np.random.default_rng(8))
    copy = _reload(robot, write_description(robot, pi, tmp_path / "stewart.xml"))
    assert np.all(copy.model.armature[[copy.model.joints[copy.model.getJointId(leg)].idx_v for leg in LEGS]] > 0)
    Theta = robot.home_actuated() + 0.01
    Thetad = np.linspace(-0.05, 0.05, 6)
    before, after = robot.plant_dynamics(Theta, Thetad, pi, None), copy.plant_dynamics(Theta, Thetad, pi, None)
    M0, bias0, M1, bias1 = before.M, before.bias, after.M, after.bias
    np.testing.assert_allclose(M1, M0, rtol=1e-10, atol=1e-12 * np.abs(M0).max())
    np.testing.assert_allclose(bias1, bias0, rtol=1e-10, atol=1e-12 * np.abs(bias0).max())


# ------------------------------------------------------------------------------ bad input
def test_bad_input_is_refused_and_nothing_written(robots, tmp_path):
    two_r, stewart = robots["2r"], robots["stewart"]
    pi = two_r.nominal_parameters()
    with pytest.raises(DescriptionError, match=r"2r\.urdf is URDF.*\(\.urdf\), not '\.xml'"):
        write_description(two_r, pi, tmp_path / "2r.xml")
    with pytest.raises(DescriptionError, match=r"stewart\.xml is MJCF.*\(\.xml or \.mjcf\), not '\.urdf'"):
        write_description(stewart, stewart.nominal_parameters(), tmp_path / "stewart.urdf")
    with pytest.raises(ValueError, match=r"26 values \(20 body values, 6 drive terms\) expected, got shape \(25,\)"):
        write_description(two_r, pi[:-1], tmp_path / "a.urdf")
    with pytest.raises(DescriptionError, match="overwrite the source"):
        write_description(two_r, pi, two_r.path)

    def refused(change, match):
        bad = pi.copy()
        change(bad)
        with pytest.raises(DescriptionError, match=match):
            write_description(two_r, bad, tmp_path / "bad.urdf")

    refused(lambda p: p.__setitem__(10, -2.0), r"body 'link2' has a negative mass \(-2\.0 kg\): no mass "
                                               r"distribution has these values")
    refused(lambda p: p.__setitem__(slice(10, 11), 0.0), r"body 'link2' has no mass but a first moment")
    refused(lambda p: p.__setitem__(19, 0.0), r"body 'link2' has principal moments of inertia about the centre of "
                                              r"mass \[-0\.045, .*\] kg·m² that are not positive semidefinite")
    # link2 about its centre of mass: Izz = 0.07 - 2 * 0.15² = 0.025 > Ixx + Iyy = 0.0158
    refused(lambda p: p.__setitem__(19, 0.07), r"body 'link2' has principal moments .* that violate the triangle "
                                              r"inequality A \+ B >= C")
    refused(lambda p: p.__setitem__(21, -0.1), r"negative drive term fv_elbow = -0\.1 \(joint 'joint2'\)")
    nan = pi.copy()
    nan[3] = np.nan
    with pytest.raises(ValueError, match=r"not finite: link1\.mz"):
        write_description(two_r, nan, tmp_path / "bad.urdf")
    assert not list(tmp_path.iterdir())


def test_a_massless_body_with_rotational_inertia_only(robots, tmp_path):
    """pinocchio takes a body without mass but with inertia (a thin rotor): written, read back."""
    robot = robots["stewart"]
    pi = robot.nominal_parameters()
    j = robot.body_names.index("leg1_cross")
    pi[10 * j:10 * j + 10] = [0, 0, 0, 0, 1e-4, 1e-5, 2e-4, 0, 0, 2.5e-4]
    to = write_description(robot, pi, tmp_path / "stewart.xml")
    inertial = next(el for el in ET.parse(to).getroot().iter("body") if el.get("name") == "leg1_cross").find("inertial")
    assert inertial.get("mass") == "0" and inertial.get("pos") == "0 0 0"
    got = load_description(to).model.inertias[j + 1].toDynamicParameters()
    np.testing.assert_allclose(got, pi[10 * j:10 * j + 10], rtol=0, atol=1e-16)


def test_the_delta_test_vector_arm_is_refused(robots, tmp_path):
    """The spec's test-vector arm (``nominal_parameters``, Table 1 read as printed) is against the
    triangle inequality: no description file is written for it (pinocchio would read it; no mass
    distribution has it)."""
    robot = robots["delta"]
    pi = robot.nominal_parameters()
    pi[:10] = dh.delta_bodies(nominal_parameters(), DeltaGeometry())["arm1"]
    with pytest.raises(DescriptionError, match=r"body 'arm1' has principal moments .* violate the triangle"):
        write_description(robot, pi, tmp_path / "delta.xml")
    assert not list(tmp_path.iterdir())


def test_a_solver_s_rounding_is_projected(robots, tmp_path):
    """A physically consistent set from an SDP solver sits on the boundary to ~1e-10: a massless
    cross a rounding below 0, a rod's zero axial moment slightly negative, a drive term -1e-12.
    Written projected onto the physical set (within 1e-9 of each body's size), read back so."""
    robot = robots["3prrr"]
    pi = robot.nominal_parameters()
    n = len(robot.actuated_joints)
    pi[len(pi) - 3 * n:] = np.linspace(0.1, 1.0, 3 * n)
    exact = pi.copy()
    j = robot.body_names.index("link1_1")
    assert np.allclose(pi[10 * j + 1:10 * j + 4] / pi[10 * j], [0.15, 0, 0])   # a rod along x
    pi[10 * j + 4] = exact[10 * j + 4] = 0.0            # without axial inertia (Ixx about the joint)...
    pi[10 * j + 4] -= 1e-13                             # ...the axial moment -1e-13
    pi[len(pi) - 3 * n] = -1e-12                        # fv of the first actuator
    to = write_description(robot, pi, tmp_path / "3prrr.xml")
    copy = _reload(robot, to)
    got = copy.nominal_parameters()
    exact[len(pi) - 3 * n] = 0.0
    _assert_bodies_close(got[:len(pi) - 3 * n], exact[:len(pi) - 3 * n], robot)
    np.testing.assert_allclose(got[len(pi) - 3 * n:], exact[len(pi) - 3 * n:], rtol=1e-15)
    inertial = next(el for el in ET.parse(to).getroot().iter("body") if el.get("name") == "link1_1").find("inertial")
    assert min(float(x) for x in inertial.get("fullinertia").split()[:3]) >= 0.0
    # beyond the tolerance it is an unphysical body
    pi[10 * j + 4] -= 1e-6
    with pytest.raises(DescriptionError, match="body 'link1_1' has principal moments"):
        write_description(robot, pi, tmp_path / "again.xml")
