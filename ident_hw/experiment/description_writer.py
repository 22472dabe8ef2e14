"""Identified parameters written back into a robot's description file (MJCF or URDF).

:func:`write_description` writes a copy of a :class:`~ident_hw.model.described.DescribedRobot`'s
file, in the same format, that carries a parameter vector of the robot
(``DescribedRobot.parameter_names``):

- each tree joint's body carries the identified inertia of its ten values (mass, first moment and
  inertia about the *joint frame's* origin, in the joint frame) converted to what the formats
  hold: the centre of mass and the inertia about it, in the body's own frame (the body frame's
  placement relative to the joint: pinocchio's BODY frame; an MJCF ``<joint pos>`` or a rotated
  body moves it). MJCF ``<inertial pos mass fullinertia/>`` (``diaginertia="0 0 0"`` for a body
  without inertia); URDF ``<inertial>`` with ``<origin xyz rpy="0 0 0"/>``, ``<mass/>``,
  ``<inertia/>`` in the child link's frame;
- a body without a joint of its own (an MJCF body without ``<joint>``, a URDF link on a fixed
  joint) is *merged* by pinocchio into the body of the joint that carries it: the identified value
  of that joint already holds it, so a merged body is written massless (an explicit zero
  ``<inertial>`` where it had one or has geometry that MuJoCo would give a mass); a body fixed to
  the world (merged into no joint) is left as it is;
- each actuated joint carries the identified drive terms: MJCF ``damping`` = fv (viscous),
  ``frictionloss`` = fc (Coulomb), ``armature`` = Jm (reflected rotor inertia), attributes of the
  ``<joint>`` (they override any ``<default>`` class); URDF ``<dynamics damping=fv friction=fc/>``.
  URDF has no element for a rotor inertia: neither pinocchio's URDF parser nor MuJoCo's URDF
  import reads one (both read ``damping`` and ``friction`` only), so Jm goes into a comment in the
  ``<joint>`` and is lost to every URDF consumer (a DescribedRobot of the written URDF has Jm 0);
- a header comment says the file was written by ident_hw from identified parameters;
- everything else is the source's (geometry, closures, limits, sites, comments: the ones before
  and after the root element verbatim, the ones inside it as ElementTree keeps them), except the
  ``<compiler>`` options that would override the written inertias in pinocchio or MuJoCo:
  ``inertiafromgeom="true"`` (ignores every ``<inertial>``), ``boundmass``, ``boundinertia``,
  ``balanceinertia``, ``settotalmass``; they are dropped and the header names them.

Values are written as Python's shortest exact ``repr`` of the double (a round trip gives the
vector back to rounding, ~1e-16 of each body's scale; values below 1e-14 of their body's scale, the
rounding of the frame change, are written 0); the output is byte-identical for the same inputs
(no date, no path: the source is named by its file name). Asset files (meshes, includes) are
referred to as in the source: write the copy next to it, or copy them.

What the readers accept, and what the writer refuses (:class:`DescriptionError` naming the body):

- pinocchio reads any body with ``m >= 0`` (its MJCF parser clamps a negative mass or diagonal
  inertia to 0), a massless body with rotational inertia, and a tensor that violates the
  triangle inequality as written. The writer refuses every body that no mass distribution
  realises: its pseudo-inertia ``[[Σ, h], [hᵀ, m]]`` (``Σ = ½ tr(I) 1 − I``, Wensing et al.)
  has an eigenvalue below −1e-9 of its largest entry: a negative mass, a first moment without
  mass, an inertia about the centre of mass that is not positive semidefinite or whose principal
  moments violate ``A + B >= C`` (the Delta's test-vector arm). A body outside by less (an SDP
  solver's tolerance: the physically consistent set of ``ident-hw export``) is projected onto the
  physical set (its pseudo-inertia's negative eigenvalues set to 0; a mass and first moment
  within that tolerance of 0 written 0), and so is a drive term within 1e-9 of 0 (written 0);
  a negative one beyond is refused. A massless body with rotational inertia only is written with
  its centre of mass at the frame origin;
- MuJoCo refuses more (``mujoco.MjModel.from_xml_path``): a moving body (one with a joint) whose
  mass or a principal moment of inertia is below ``mjMINVAL`` = 1e-15 (unless a static child
  carries mass, which a written file never has: merged bodies are massless), an MJCF
  ``fullinertia`` whose smallest eigenvalue is below 1e-14, and principal moments that violate
  ``A + B >= C`` exactly (a flat plate on the boundary may fail by rounding). The shipped
  descriptions have such bodies (massless universal-joint crosses, point-mass carriages, slender
  rods without axial inertia), so they are written for pinocchio by default;
  ``for_mujoco=True`` refuses them.

Every written file is read back with pinocchio before it replaces ``to``: a value that does not
come back (a reader quirk) is an error, never a silently different file.
"""

from __future__ import annotations

import os
import re
import textwrap
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from ident_hw.model.described import BODY_PARAMS, DescribedRobot, DescriptionError, load_description
from ident_hw.model.pseudo_inertia import pseudo_inertia

MJCF, URDF = "MJCF", "URDF"
SUFFIXES = {MJCF: (".xml", ".mjcf"), URDF: (".urdf",)}
#: MuJoCo's smallest mass and principal moment of a moving body (``mjMINVAL``)
MJ_MINVAL = 1e-15
#: MuJoCo's smallest eigenvalue of an MJCF ``fullinertia``
MJ_FULLINERTIA_MIN = 1e-14
#: ``<compiler>`` attributes that change the inertias pinocchio or MuJoCo read from ``<inertial>``
OVERRIDING_COMPILER = ("boundmass", "boundinertia", "balanceinertia", "settotalmass")
#: relative size (of a body's scale) below which a written value is rounding: written 0
_ZERO = 1e-14
#: relative agreement of the written file, read back by pinocchio, with the vector
_READ_BACK = 1e-10
#: how far outside the physical set (of a body's size, of a drive term's kind) is a solver's rounding
_PHYSICAL_TOL = 1e-9
_HEADER_START = "Written by ident_hw"
# the vector's body values are pinocchio's dynamic parameters, in this order (_tensor reads them)
assert BODY_PARAMS == ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
_JM_COMMENT = "ident_hw: Jm"


@dataclass(frozen=True)
class BodyInertial:
    """One moving body as the description formats hold it: its ``mass`` (kg), centre of mass
    ``com`` (3,) (m) and ``inertia`` (3, 3) about the centre of mass (kg·m²), both in the body's
    own frame (MJCF body, URDF child link)."""

    name: str
    mass: float
    com: np.ndarray
    inertia: np.ndarray

    def principal_moments(self) -> np.ndarray:
        """The principal moments (3,) about the centre of mass, ascending."""
        return np.linalg.eigvalsh(self.inertia)


@dataclass(frozen=True)
class Drive:
    """The drive terms of one actuated joint (SI, per :data:`~ident_hw.model.described.DRIVE_PARAMS`):
    ``fc`` the sliding Coulomb force (of a Maxwell-slip model, the sum of its elements' forces);
    ``unwritten``: the friction model's terms a description file has no attribute for (an offset
    ``f0``, a Stribeck term ``fs``), by name, written as a comment."""

    joint: str
    actuator: str
    fv: float
    fc: float
    Jm: float
    unwritten: tuple[tuple[str, float], ...] = ()


def description_format(path: str | Path) -> str:
    """``"MJCF"`` or ``"URDF"`` from a file's suffix (raises :class:`DescriptionError`)."""
    suffix = Path(path).suffix.lower()
    for fmt, suffixes in SUFFIXES.items():
        if suffix in suffixes:
            return fmt
    raise DescriptionError(f"{path}: unknown description format {suffix!r}; expected MJCF (.xml, .mjcf) or "
                           "URDF (.urdf)")


def physical_vector(robot: DescribedRobot, params) -> np.ndarray:
    """``params`` (P,) as written (a copy): a body outside the physical set by rounding projected
    onto it, a mass and first moment within rounding of 0 set to 0, a drive term within rounding
    below 0 set to 0 (see the module docstring); a physical body away from those is unchanged.

    Raises:
        ValueError: a vector of the wrong length or not finite.
        DescriptionError: a body no mass distribution realises, a negative drive term (named).
    """
    params = _checked_vector(robot, params).copy()
    for j, name in enumerate(robot.body_names):
        params[10 * j:10 * j + 10] = _physical_body(name, params[10 * j:10 * j + 10], robot.path)
    names = robot.parameter_names
    for key in ("fv", "fc", "Jm", *(t for t in robot.friction.extra_terms if t.startswith("fc"))):
        index = [names.index(f"{key}_{a}") for a in robot.actuator_names]
        values = params[index]
        tol = _PHYSICAL_TOL * max(1.0, float(np.abs(values).max()))
        bad = [f"{key}_{a} = {float(v)!r} (joint {j!r})"
               for a, j, v in zip(robot.actuator_names, robot.actuated_joints, values) if v < -tol]
        if bad:
            raise DescriptionError(f"{robot.path.name}: negative drive term {', '.join(bad)}: friction and rotor "
                                   "inertia cannot be negative")
        params[index] = np.maximum(values, 0.0)
    return params


def body_inertials(robot: DescribedRobot, params) -> tuple[BodyInertial, ...]:
    """The tree bodies (one per tree joint, pinocchio's order) of :func:`physical_vector`
    ``(robot, params)`` in their own frames (raises as it does)."""
    params = physical_vector(robot, params)
    own = _own_body_frames(robot)
    return tuple(_in_body_frame(own[j].name, params[10 * (j - 1):10 * j], own[j].placement)
                 for j in range(1, robot.model.njoints))


def drive_terms(robot: DescribedRobot, params) -> tuple[Drive, ...]:
    """The drive terms of :func:`physical_vector` ``(robot, params)`` per actuated joint."""
    params = physical_vector(robot, params)
    return _drives(robot, params)


def _drives(robot: DescribedRobot, params: np.ndarray) -> tuple[Drive, ...]:
    """The drive terms of ``params`` (P,) per actuated joint, by name (:class:`Drive`)."""
    names = robot.parameter_names
    coulomb = ("fc", *(t for t in robot.friction.extra_terms if t.startswith("fc")))
    other = tuple(t for t in robot.friction.extra_terms if not t.startswith("fc"))

    def value(term: str, actuator: str) -> float:
        return float(params[names.index(f"{term}_{actuator}")])
    return tuple(Drive(joint, a, value("fv", a), sum(value(t, a) for t in coulomb), value("Jm", a),
                       tuple((t, value(t, a)) for t in other))
                 for joint, a in zip(robot.actuated_joints, robot.actuator_names))


def mujoco_problems(bodies, fmt: str = MJCF) -> list[str]:
    """What MuJoCo's compiler would refuse in the moving ``bodies`` (:func:`body_inertials`) once
    written in format ``fmt`` (one line each; empty: MuJoCo loads them)."""
    problems = []
    for body in bodies:
        moments = body.principal_moments()
        if body.mass < MJ_MINVAL or moments[0] < MJ_MINVAL:
            problems.append(f"{body.name}: a moving body needs a mass and principal moments of inertia of at least "
                            f"{MJ_MINVAL:g} (mass {body.mass:.6g} kg, principal moments "
                            f"{_fmt_list(moments)} kg·m²)")
            continue
        if fmt == MJCF and not _is_zero(body.inertia) and moments[0] < MJ_FULLINERTIA_MIN:
            problems.append(f"{body.name}: an MJCF fullinertia needs eigenvalues of at least {MJ_FULLINERTIA_MIN:g} "
                            f"(principal moments {_fmt_list(moments)} kg·m²)")
            continue
        a, b, c = moments
        if a + b < c:
            problems.append(f"{body.name}: the principal moments {_fmt_list(moments)} kg·m² violate the triangle "
                            "inequality A + B >= C (no mass distribution has them)")
    return problems


def write_description(robot: DescribedRobot, params, to: str | Path, *, for_mujoco: bool = False) -> Path:
    """Write a copy of ``robot.path`` carrying ``params`` (P,) to ``to`` (see the module docstring).

    Args:
        robot: the robot whose description is copied (its tree, actuated joints and names).
        params: a parameter vector of ``robot`` (``DescribedRobot.parameter_names`` order).
        to: the file to write, in the source's format (MJCF: ``.xml`` or ``.mjcf``; URDF: ``.urdf``);
            its directory is created. It cannot be the source itself.
        for_mujoco: also refuse bodies MuJoCo's compiler would refuse (:func:`mujoco_problems`).

    Returns:
        ``to`` as a :class:`~pathlib.Path`.

    Raises:
        ValueError: ``params`` of the wrong length or not finite.
        DescriptionError: ``to`` of another format than the source, a body no mass distribution
            realises (negative mass, first moment without mass, inertia about the centre of mass
            not positive semidefinite or against the triangle inequality; with ``for_mujoco``:
            what MuJoCo refuses), a negative drive term, a source whose tree bodies or joints the
            writer cannot find, or a written file pinocchio reads back differently.
    """
    source = Path(robot.path)
    fmt = description_format(source)
    to = Path(to)
    if to.suffix.lower() not in SUFFIXES[fmt]:
        given = repr(to.suffix) if to.suffix else "without a suffix"
        raise DescriptionError(f"{to}: the source {source.name} is {fmt}, written as {fmt} "
                               f"({' or '.join(SUFFIXES[fmt])}), not {given}")
    if to.exists() and to.resolve() == source.resolve():
        raise DescriptionError(f"{to}: would overwrite the source description; write the copy elsewhere")
    params = physical_vector(robot, params)
    bodies = body_inertials(robot, params)
    drives = drive_terms(robot, params)
    if for_mujoco:
        problems = mujoco_problems(bodies, fmt)
        if problems:
            raise DescriptionError(f"{source.name}: MuJoCo would refuse the written file:\n  " + "\n  ".join(problems))

    text = source.read_bytes()
    root = _parse(source, text)
    merged = _merged_body_names(robot)
    if fmt == MJCF:
        dropped = _write_mjcf(root, source, bodies, merged, drives)
        geometry: list[str] = []
    else:
        dropped = _write_urdf(root, source, bodies, merged, drives)
        geometry = _urdf_meshes(root, source, to, for_mujoco)
    out = _assemble(source, text, root, fmt, dropped, geometry)

    to.parent.mkdir(parents=True, exist_ok=True)
    tmp = to.with_name(f".{to.stem}.ident_hw-tmp{to.suffix}")
    try:
        with open(tmp, "w", encoding="utf-8", newline="\n") as f:
            f.write(out)
        _read_back(robot, params, tmp, fmt, to)
        os.replace(tmp, to)
    finally:
        if tmp.exists():
            tmp.unlink()
    return to


# ---------------------------------------------------------------------------------- the values
def _checked_vector(robot: DescribedRobot, params) -> np.ndarray:
    params = np.asarray(params, dtype=float)
    size = len(robot.parameter_names)
    if params.shape != (size,):
        raise ValueError(f"{robot.path.name}: a parameter vector of {size} values "
                         f"({10 * len(robot.body_names)} body values, "
                         f"{size - 10 * len(robot.body_names)} drive terms) expected, got shape {params.shape}")
    if not np.all(np.isfinite(params)):
        bad = [robot.parameter_names[i] for i in np.flatnonzero(~np.isfinite(params))]
        raise ValueError(f"{robot.path.name}: parameters not finite: {', '.join(bad)}")
    return params


def _own_body_frames(robot: DescribedRobot) -> dict[int, pin.Frame]:
    """The body frame of each tree joint: the first BODY frame on it (the body the joint moves,
    as :attr:`DescribedRobot.body_names` names it)."""
    model = robot.model
    own: dict[int, pin.Frame] = {}
    for frame in model.frames:
        if frame.type == pin.FrameType.BODY and frame.parentJoint > 0 and frame.parentJoint not in own:
            own[frame.parentJoint] = frame
    for j in range(1, model.njoints):
        if j not in own:
            raise DescriptionError(f"{robot.path}: joint {model.names[j]!r} moves no body pinocchio names: "
                                   "nowhere to write its inertia")
    return own


def _merged_body_names(robot: DescribedRobot) -> list[str]:
    """Bodies pinocchio merged into a tree joint's inertia (BODY frames on a joint, not its own)."""
    own = {frame.name for frame in _own_body_frames(robot).values()}
    return [f.name for f in robot.model.frames
            if f.type == pin.FrameType.BODY and f.parentJoint > 0 and f.name not in own]


def _physical_body(name: str, p: np.ndarray, where: Path) -> np.ndarray:
    """A body's ten values, checked through its pseudo-inertia ``J`` and projected onto ``J ⪰ 0``
    where it is outside by rounding (``_PHYSICAL_TOL`` of its largest entry)."""
    m, h, I = float(p[0]), np.asarray(p[1:4], dtype=float), _tensor(p[4:10])
    J = pseudo_inertia(p)
    size = float(np.abs(J).max())
    if size == 0.0:
        return np.zeros(10)
    tol = _PHYSICAL_TOL * size
    w, V = np.linalg.eigh(J)
    if w[0] < -tol:
        if m < -tol:
            why = f"a negative mass ({m!r} kg)"
        elif m <= tol:
            why = f"no mass but a first moment {_fmt_list(h)} kg·m (no centre of mass)"
        else:
            c = h / m
            moments = np.linalg.eigvalsh(I - m * (c @ c * np.eye(3) - np.outer(c, c)))
            why = (f"principal moments of inertia about the centre of mass {_fmt_list(moments)} kg·m² "
                   + ("that are not positive semidefinite" if moments[0] < -tol else
                      "that violate the triangle inequality A + B >= C"))
        raise DescriptionError(f"{where.name}: body {name!r} has {why}: no mass distribution has these values, "
                               f"not a physical body (pseudo-inertia eigenvalue {w[0]:.3g})")
    if w[0] < 0.0:
        J = (V * np.maximum(w, 0.0)) @ V.T
        J = 0.5 * (J + J.T)
    m, h, sigma = float(J[3, 3]), J[:3, 3].copy(), J[:3, :3]
    if m <= tol and float(np.abs(h).max()) <= tol:
        m, h = 0.0, np.zeros(3)
    I = np.trace(sigma) * np.eye(3) - sigma
    return np.array([m, *h, I[0, 0], I[0, 1], I[1, 1], I[0, 2], I[1, 2], I[2, 2]])


def _in_body_frame(name: str, p: np.ndarray, joint_M_body: pin.SE3) -> BodyInertial:
    """A (physical) body's ten values about its joint frame, converted to its own frame.

    With ``x_joint = R x_body + t`` (``joint_M_body``): ``c_body = R^T (c - t)`` and
    ``I_body = R^T I_C R``, ``I_C = I_O - m ([c]x [c]x^T)`` the inertia about the centre of mass
    (joint axes). Written with numpy rather than ``pin.Inertia.se3ActionInverse``: pinocchio's
    ``Inertia`` refuses a tensor with a rounding-size negative eigenvalue (a rod about its axis)."""
    m, h, I_O = float(p[0]), np.asarray(p[1:4], dtype=float), _tensor(p[4:10])
    c = h / m if m > 0 else np.zeros(3)
    I_C = I_O - m * (c @ c * np.eye(3) - np.outer(c, c))
    # the size of the rounding of I_C (and of the frame change below)
    scale_I = max(float(np.abs(I_O).max()), float(m * (c @ c)))
    R, t = joint_M_body.rotation, joint_M_body.translation
    com = R.T @ (c - t) if m > 0 else np.zeros(3)
    I_body = R.T @ I_C @ R
    I_body = 0.5 * (I_body + I_body.T)
    com[np.abs(com) < _ZERO * max(float(np.abs(com).max()), 1e-300)] = 0.0
    I_body[np.abs(I_body) < _ZERO * max(scale_I, 1e-300)] = 0.0
    return BodyInertial(name, m, com, I_body)


def _tensor(six) -> np.ndarray:
    """3×3 from ``Ixx, Ixy, Iyy, Ixz, Iyz, Izz`` (pinocchio's order, :data:`BODY_PARAMS`)."""
    xx, xy, yy, xz, yz, zz = six
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]], dtype=float)


def _is_zero(I: np.ndarray) -> bool:
    return not np.any(I)


def _num(x: float) -> str:
    """The shortest exact text of a double (``-0`` written ``0``, ``2.0`` written ``2``)."""
    text = repr(float(x) + 0.0)
    return text[:-2] if text.endswith(".0") else text


def _nums(values) -> str:
    return " ".join(_num(v) for v in values)


def _fmt_list(values) -> str:
    return "[" + ", ".join(f"{v:.6g}" for v in values) + "]"


# ---------------------------------------------------------------------------------- the XML
def _parse(source: Path, text: bytes) -> ET.Element:
    """The root element (comments and processing instructions inside it kept); the file's
    namespace prefixes registered so that they are written back as they were."""
    try:
        for _, (prefix, uri) in ET.iterparse(source, events=("start-ns",)):
            try:
                ET.register_namespace(prefix, uri)
            except ValueError:
                pass
        parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True, insert_pis=True))
        parser.feed(text)
        return parser.close()
    except ET.ParseError as exc:
        raise DescriptionError(f"{source}: not well-formed XML: {exc}") from None


def _named(elements) -> dict[str, ET.Element | None]:
    """``{name: element}``; a name given twice maps to None (an error only where it is needed)."""
    out: dict[str, ET.Element | None] = {}
    for name, el in elements:
        out[name] = None if name in out else el
    return out


def _find(named: dict, name: str, what: str, source: Path) -> ET.Element:
    if name not in named:
        raise DescriptionError(f"{source}: no {what} {name!r} in the file (pinocchio has one; an <include> or a "
                               "changed file?)")
    if named[name] is None:
        raise DescriptionError(f"{source}: two {what}s named {name!r}: cannot tell which to write")
    return named[name]


def _mjcf_tree(root: ET.Element, source: Path) -> tuple[dict, dict]:
    """``({body name: <body>}, {joint name: <joint>})`` of the tree pinocchio reads (the first body
    under ``<worldbody>``), named as pinocchio names them (an unnamed body: its parent's name +
    ``Bis``; an unnamed joint: its body's name + ``Joint_<k>``)."""
    world = root.find("worldbody")
    first = world.find("body") if world is not None else None
    if first is None:
        raise DescriptionError(f"{source}: no <body> under <worldbody>")
    bodies, joints = [], []

    def walk(el: ET.Element, parent: str) -> None:
        name = el.get("name") or parent + "Bis"
        bodies.append((name, el))
        k = 0
        for child in el:
            if child.tag in ("joint", "freejoint"):
                joints.append((child.get("name") or f"{name}Joint_{k}", child))
                k += 1
            elif child.tag == "body":
                walk(child, name)

    walk(first, "")
    return _named(bodies), _named(joints)


def _indent_of(parent: ET.Element, depth: int) -> tuple[str, str]:
    """The whitespace before a child of ``parent`` and before its closing tag."""
    children = list(parent)
    if children and parent.text and parent.text.strip() == "":
        return parent.text, children[-1].tail or "\n" + "  " * depth
    return "\n" + "  " * (depth + 1), "\n" + "  " * depth


def _insert(parent: ET.Element, index: int, child: ET.Element[Any], depth: int) -> None:
    """Insert ``child`` at ``index`` with the indentation of its siblings."""
    inner, outer = _indent_of(parent, depth)
    children = list(parent)
    if not children:
        parent.text = inner
        child.tail = outer
    elif index >= len(children):
        children[-1].tail = inner
        child.tail = outer
    else:
        child.tail = inner
        if index == 0:
            parent.text = inner
    parent.insert(index, child)


def _depths(root: ET.Element) -> dict[ET.Element, int]:
    depth = {root: 0}
    for el in root.iter():
        for child in el:
            depth[child] = depth[el] + 1
    return depth


def _drop_overriding_compiler(compilers) -> list[str]:
    dropped = []
    for compiler in compilers:
        for key in OVERRIDING_COMPILER:
            if key in compiler.attrib:
                dropped.append(f'{key}="{compiler.attrib.pop(key)}"')
        if compiler.get("inertiafromgeom", "").strip().lower() == "true":
            dropped.append(f'inertiafromgeom="{compiler.attrib.pop("inertiafromgeom")}"')
    return dropped


def _write_mjcf(root, source, bodies, merged, drives) -> list[str]:
    named_bodies, named_joints = _mjcf_tree(root, source)
    depth = _depths(root)
    for body in bodies:
        el = _find(named_bodies, body.name, "body", source)
        if (body.mass == 0 and _is_zero(body.inertia) and el.find("inertial") is None
                and el.find("geom") is None):
            continue                    # massless already (a universal joint's cross): left as it is
        attrs = {"pos": _nums(body.com), "mass": _num(body.mass)}
        if _is_zero(body.inertia):
            attrs["diaginertia"] = "0 0 0"
        else:
            I = body.inertia
            attrs["fullinertia"] = _nums([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])
        _set_mjcf_inertial(el, attrs, depth)
    for name in merged:
        el = _find(named_bodies, name, "body", source)
        if el.find("inertial") is not None or el.find("geom") is not None:
            _set_mjcf_inertial(el, {"pos": "0 0 0", "mass": "0", "diaginertia": "0 0 0"}, depth)
    for drive in drives:
        el = _find(named_joints, drive.joint, "joint", source)
        el.set("damping", _num(drive.fv))
        el.set("frictionloss", _num(drive.fc))
        el.set("armature", _num(drive.Jm))
        _comment_unwritten(el, drive, depth)
    return _drop_overriding_compiler(root.findall("compiler"))


def _set_mjcf_inertial(body: ET.Element, attrs: dict, depth: dict) -> None:
    inertial = body.find("inertial")
    if inertial is None:
        inertial = ET.Element("inertial")
        children = list(body)
        after = [k for k, child in enumerate(children) if child.tag in ("joint", "freejoint")]
        _insert(body, after[-1] + 1 if after else 0, inertial, depth[body])
    inertial.attrib.clear()
    inertial.attrib.update(attrs)


def _write_urdf(root, source, bodies, merged, drives) -> list[str]:
    links = _named((el.get("name", ""), el) for el in root.findall("link"))
    joints = _named((el.get("name", ""), el) for el in root.findall("joint"))
    depth = _depths(root)
    for body in bodies:
        I = body.inertia
        _set_urdf_inertial(_find(links, body.name, "link", source), body.com, body.mass,
                           [I[0, 0], I[0, 1], I[0, 2], I[1, 1], I[1, 2], I[2, 2]], depth)
    for name in merged:
        link = _find(links, name, "link", source)
        if link.find("inertial") is not None or link.find("collision") is not None:
            _set_urdf_inertial(link, np.zeros(3), 0.0, np.zeros(6), depth)
    for drive in drives:
        joint = _find(joints, drive.joint, "joint", source)
        dynamics = joint.find("dynamics")
        if dynamics is None:
            dynamics = ET.Element("dynamics")
            _insert(joint, len(joint), dynamics, depth[joint])
            depth[dynamics] = depth[joint] + 1
        dynamics.set("damping", _num(drive.fv))
        dynamics.set("friction", _num(drive.fc))
        for old in [c for c in joint if c.tag is ET.Comment and (c.text or "").strip().startswith(_JM_COMMENT)]:
            _remove(joint, old)
        unit = "kg·m²" if joint.get("type") in ("revolute", "continuous") else "kg"
        comment = ET.Comment(f" {_JM_COMMENT} = {_num(drive.Jm)} {unit} (reflected rotor inertia of actuator "
                             f"{drive.actuator}): URDF has no element for it, pinocchio and MuJoCo read none ")
        children = list(joint)
        _insert(joint, children.index(dynamics) + 1, comment, depth[joint])
        _comment_unwritten(joint, drive, depth)
    return _drop_overriding_compiler(root.findall("mujoco/compiler"))


#: the start of the comment that holds a joint's friction terms no attribute can
_UNWRITTEN_COMMENT = "ident_hw: friction terms"


def _comment_unwritten(joint, drive: Drive, depth) -> None:
    """A comment in ``joint`` with the friction terms no attribute of the format holds (an
    offset ``f0``, a Stribeck term ``fs``; the Coulomb attribute holds the sliding force), an
    older one of ours replaced; nothing when there are none."""
    for old in [c for c in joint if c.tag is ET.Comment and (c.text or "").strip().startswith(_UNWRITTEN_COMMENT)]:
        _remove(joint, old)
    if not drive.unwritten:
        return
    text = ", ".join(f"{name} = {_num(value)}" for name, value in drive.unwritten)
    comment = ET.Comment(f" {_UNWRITTEN_COMMENT} of actuator {drive.actuator} no attribute holds (SI): {text}; the "
                         "Coulomb attribute is the sliding force of its friction model ")
    _insert(joint, len(joint), comment, depth.get(joint, 0))


def _set_urdf_inertial(link: ET.Element, com, mass: float, six, depth: dict) -> None:
    """``<inertial>`` of a link: origin (rpy 0), mass, inertia ``ixx ixy ixz iyy iyz izz``."""
    inertial = link.find("inertial")
    if inertial is None:
        inertial = ET.Element("inertial")
        _insert(link, 0, inertial, depth[link])
    d = depth[link] + 1
    for child in list(inertial):
        inertial.remove(child)
    inertial.text = None
    for k, (tag, attrs) in enumerate((
            ("origin", {"xyz": _nums(com), "rpy": "0 0 0"}),
            ("mass", {"value": _num(mass)}),
            ("inertia", dict(zip(("ixx", "ixy", "ixz", "iyy", "iyz", "izz"), (_num(v) for v in six)))))):
        _insert(inertial, k, ET.Element(tag, attrs), d)


def _remove(parent: ET.Element, child: ET.Element) -> None:
    """Remove ``child`` keeping the whitespace around its siblings."""
    children = list(parent)
    k = children.index(child)
    if k == len(children) - 1 and k > 0:
        children[k - 1].tail = child.tail
    parent.remove(child)


# ---------------------------------------------------------------------------------- the file
def _prolog(text: str) -> str:
    """The text before the root element: declaration, comments, doctype and the whitespace between."""
    i = 0
    while True:
        while i < len(text) and text[i].isspace():
            i += 1
        if text.startswith("<?", i):
            i = text.index("?>", i) + 2
        elif text.startswith("<!--", i):
            i = text.index("-->", i) + 3
        elif text.startswith("<!DOCTYPE", i):
            bracket = text.find("[", i, text.index(">", i))
            i = text.index(">", text.index("]", bracket) if bracket >= 0 else i) + 1
        else:
            return text[:i]


def _urdf_meshes(root: ET.Element, source: Path, to: Path, for_mujoco: bool) -> list[str]:
    """The URDF's mesh files where the copy finds them: a file name relative to the source
    rewritten relative to the copy's folder; a ``package://`` name (a ROS package, which neither
    pinocchio nor MuJoCo resolves) or a file that does not exist kept as it is, or with
    ``for_mujoco`` its ``<visual>`` or ``<collision>`` dropped (MuJoCo refuses a file whose meshes
    it cannot open; the inertias do not depend on them). Returns the mesh names dropped."""
    dropped = []
    for link in root.findall("link"):
        for kind in ("visual", "collision"):
            for element in link.findall(kind):
                mesh = element.find("geometry/mesh")
                if mesh is None or not mesh.get("filename"):
                    continue
                name = mesh.get("filename") or ""
                local = None if "://" in name else (source.parent / name)
                if local is not None and local.is_file():
                    mesh.set("filename", os.path.relpath(local.resolve(), to.resolve().parent))
                elif for_mujoco:
                    _remove(link, element)
                    dropped.append(name)
    return sorted(set(dropped))


def _assemble(source: Path, raw: bytes, root: ET.Element, fmt: str, dropped: list[str],
              geometry: Sequence[str] = ()) -> str:
    """The written text: the source's prolog with the header, the root, the source's epilog."""
    try:
        text = raw.decode("utf-8").replace("\r\n", "\n")
    except UnicodeDecodeError:
        raise DescriptionError(f"{source}: not UTF-8 text") from None
    prolog = _prolog(text)
    tag = root.tag
    end = text.rfind(f"</{tag}")
    epilog = text[text.index(">", end) + 1:] if end >= 0 else "\n"
    if not epilog.endswith("\n"):
        epilog += "\n"
    # a header of an earlier write is replaced, not stacked
    prolog = re.sub(r"<!--\s*" + _HEADER_START + r".*?-->\n?", "", prolog, flags=re.DOTALL)
    prolog = re.sub(r"""(<\?xml[^>]*?encoding\s*=\s*)(["'])[^"']*\2""", r'\1"UTF-8"', prolog)
    header = _header(source.name, fmt, dropped, geometry)
    declaration = re.match(r"\s*<\?xml.*?\?>", prolog, flags=re.DOTALL)
    if declaration:
        k = declaration.end()
        prolog = prolog[:k] + "\n" + header + prolog[k:]
    else:
        prolog = header + "\n" + prolog
    return prolog + _serialize(root) + epilog


def _serialize(root: ET.Element) -> str:
    """The root as text, empty elements closed ``<tag/>`` as the description files write them
    (ElementTree writes ``<tag />``; comments and processing instructions left as they are)."""
    parts = re.split(r"(<!--.*?-->|<\?.*?\?>)", ET.tostring(root, encoding="unicode"), flags=re.DOTALL)
    return "".join(part if k % 2 else part.replace(" />", "/>") for k, part in enumerate(parts))


def _header(name: str, fmt: str, dropped: list[str], geometry: Sequence[str] = ()) -> str:
    name = name.replace("--", "- -")
    if fmt == MJCF:
        lines = [
            f"{_HEADER_START} from identified parameters (ident_hw.experiment.description_writer): a copy",
            f"of {name} in which each moving body carries its identified inertia (<inertial>: centre of",
            "mass, mass, inertia about the centre of mass, in the body frame); bodies without a joint of",
            "their own are massless (the identified inertia of the body that carries them holds them); the",
            "actuated joints carry the identified drive terms: damping = viscous friction fv,",
            "frictionloss = Coulomb friction fc, armature = reflected rotor inertia Jm.",
        ]
    else:
        lines = [
            f"{_HEADER_START} from identified parameters (ident_hw.experiment.description_writer): a copy",
            f"of {name} in which each moving link carries its identified inertia (<inertial> in the link",
            "frame); links on fixed joints are massless (the identified inertia of the link that carries",
            "them holds them); the actuated joints carry the identified drive terms: <dynamics>",
            "damping = viscous friction fv, friction = Coulomb friction fc. URDF has no element for the",
            "reflected rotor inertia Jm: it is in a comment in each actuated joint, read by no parser.",
        ]
    if dropped:
        lines += textwrap.wrap("Compiler options dropped (they would override the identified inertias): "
                               + ", ".join(dropped).replace("--", "- -") + ".", width=96, break_long_words=False)
    if geometry:
        lines += textwrap.wrap(f"Visual and collision elements of {len(geometry)} mesh file(s) MuJoCo cannot open "
                               "dropped (the inertias do not depend on them): "
                               + ", ".join(geometry).replace("--", "- -") + ".", width=96, break_long_words=False)
    lines.append("Everything else is the source's.")
    return "<!--\n" + "".join(f"  {line}\n" for line in lines) + "-->"


def _read_back(robot: DescribedRobot, params: np.ndarray, path: Path, fmt: str, to: Path) -> None:
    """pinocchio reads ``path`` back as ``params`` (raises :class:`DescriptionError` otherwise)."""
    try:
        model = load_description(path).model
    except DescriptionError as exc:
        raise DescriptionError(f"{to}: pinocchio cannot read the written file back: {exc}") from None
    if tuple(model.names) != tuple(robot.model.names):
        raise DescriptionError(f"{to}: pinocchio reads other joints back ({list(model.names)[1:]}) than "
                               f"{robot.path.name} has ({list(robot.model.names)[1:]})")
    bad = []
    for j in range(1, model.njoints):
        want = params[10 * (j - 1):10 * j]
        got = model.inertias[j].toDynamicParameters()
        tol = _READ_BACK * max(float(np.abs(want).max()), float(np.abs(got).max())) + 1e-300
        for name, w, g in zip(BODY_PARAMS, want, got):
            if abs(w - g) > tol:
                bad.append(f"{robot.body_names[j - 1]}.{name}: {g!r} instead of {w!r}")
    for drive in _drives(robot, params):
        v = model.joints[model.getJointId(drive.joint)].idx_v
        read: list[tuple[str, Any, float]] = [("fv", model.damping[v], drive.fv), ("fc", model.friction[v], drive.fc)]
        if fmt == MJCF:
            read.append(("Jm", model.armature[v], drive.Jm))
        for key, value, expected in read:
            if abs(value - expected) > _READ_BACK * abs(expected) + 1e-300:
                bad.append(f"{key}_{drive.actuator}: {value!r} instead of {expected!r}")
    if bad:
        raise DescriptionError(f"{to}: pinocchio reads the written file back with other values (a reader quirk "
                               "the writer does not handle):\n  " + "\n  ".join(bad))
