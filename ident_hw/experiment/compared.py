"""A parameter set from elsewhere (``identification.compare_with``): read from its file and turned
into the force predictions the report shows beside the identified ones.

The file holds named vectors as MATLAB prints them, ``name = [v1 v2 ...]`` (other lines, such as
comments, are skipped). The config names the vector of the bodies' inertial values (ten per body
of the description, in the description's body order, each named in its ``order``), of the
friction values (per actuator, in its ``order``, of its friction model), of the rotor inertias
and of the drive gains its forces were measured with. The set predicts with its own friction
model: its forces are those of a robot model with that friction (:func:`compared_model`),
prepared exactly as the identified model's (same rows, filters, decimation).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drivers.errors import RecordingError
from ident_hw.config import RobotConfig
from ident_hw.config.identification import CompareWithConfig, VectorConfig
from ident_hw.config.robots import described_model
from ident_hw.model.friction import FrictionModel
from ident_hw.model.interface import RobotModel
from ident_hw.model.pseudo_inertia import SPATIAL

#: ``name = [ ... ]``: a named vector of a parameter file
_VECTOR = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*\[([^\]]*)\]", re.MULTILINE)
#: the names a body's values may have in a ``bodies.order``, pinocchio's (SPATIAL) with ``Ixz``
#: where the products of inertia are listed in the other order
BODY_NAMES = frozenset(SPATIAL)
#: the values a ``friction.order`` may name
FRICTION_NAMES = frozenset({"fv", "fc", "f0", "fs"})


class CompareError(RecordingError):
    """A parameter file that does not fit the config (names the file and the vector)."""


@dataclass(frozen=True)
class ComparedSet:
    """A parameter set from elsewhere in the order of ``model``'s ``parameter_names``, the
    model that predicts with it (its friction model), its label and the drive gains its forces
    are measured with (a,), or None: the config's."""

    label: str
    model: RobotModel
    values: np.ndarray
    gains: np.ndarray | None

    def force_factor(self, per_amp: np.ndarray) -> np.ndarray:
        """(a,) what turns this set's predicted forces into the config's measure of them: the
        config's force per ampere ``per_amp`` (a,) over the set's gains (1 without gains)."""
        return np.ones_like(per_amp) if self.gains is None else per_amp / self.gains


def read_vectors(path: str | Path) -> dict[str, np.ndarray]:
    """The named vectors of a parameter file (``name = [v1 v2 ...]``)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CompareError(f"{path}: cannot read the parameters to compare with: {exc}") from None
    out = {}
    for match in _VECTOR.finditer(text):
        try:
            out[match.group(1)] = np.array([float(v) for v in match.group(2).replace(",", " ").split()])
        except ValueError as exc:
            raise CompareError(f"{path}: vector {match.group(1)}: {exc}") from None
    return out


def compared_model(robot_config: RobotConfig, spec: CompareWithConfig, robot: RobotModel | None = None
                   ) -> RobotModel:
    """The robot of the config's robot section ``robot_config`` with the friction model of the compared set: its ``friction.model``
    (``coulomb`` as a plain sign, ``tanh(qd / 1e-9)``), an offset where its ``order`` has ``f0``;
    ``robot``: the config's robot already built (a described robot: its copy shares its tree)."""
    friction = spec.friction
    order = friction.order if friction is not None else ()
    model = FrictionModel(kind=friction.model if friction is not None else "coulomb", width=1e-9,
                          rest_speed=robot_config.friction.rest_speed, offset="f0" in order,
                          stribeck_velocity=None)
    base = described_model(robot_config) if robot is None else robot
    from ident_hw.model.described import DescribedRobot      # pinocchio: described robots only
    if not isinstance(base, DescribedRobot):    # the config's check refuses compare_with for another robot
        raise ValueError(f"compare_with: needs a described robot's model, not the {robot_config.kind}'s")
    return base.with_friction(model)


def compared_set(robot_config: RobotConfig, spec: CompareWithConfig, robot: RobotModel | None = None) -> ComparedSet:
    """The set of ``spec`` read from its file, in the order of :func:`compared_model`'s parameters
    (``robot_config``: the config's robot section; ``robot``: its model, if built).

    Raises:
        CompareError: a vector the file does not hold, of the wrong length, or an order naming a
            value the model has no place for; the message names the file and the key.
    """
    vectors = read_vectors(spec.path)
    model = compared_model(robot_config, spec, robot)
    names = model.parameter_names
    values = np.zeros(len(names))
    bodies = sorted({n.split(".")[0] for n in names if "." in n}, key=lambda b: names.index(f"{b}.m"))
    _fill(values, names, _vector(vectors, spec.bodies, spec.path, "bodies", 10 * len(bodies)),
          [[f"{b}.{v}" for v in spec.bodies.order] for b in bodies], spec.path, "bodies", BODY_NAMES)
    actuators = model.actuator_names
    if spec.friction is not None:
        found = _vector(vectors, spec.friction, spec.path, "friction", len(spec.friction.order) * len(actuators))
        _fill(values, names, found, [[f"{v}_{a}" for v in spec.friction.order] for a in actuators], spec.path,
              "friction", FRICTION_NAMES)
    if spec.rotor is not None:
        found = _vector(vectors, spec.rotor, spec.path, "rotor", len(actuators))
        _fill(values, names, found, [[f"Jm_{a}"] for a in actuators], spec.path, "rotor", {"Jm"})
    gains = None if spec.gains is None else _vector(vectors, spec.gains, spec.path, "gains", len(actuators))
    return ComparedSet(spec.label, model, values, gains)


def _vector(vectors: dict[str, np.ndarray], vector: VectorConfig, path: str, key: str, length: int) -> np.ndarray:
    if vector.vector not in vectors:
        raise CompareError(f"{path}: identification.compare_with.{key}.vector: no vector {vector.vector!r} in the "
                           f"file (it holds {sorted(vectors)})")
    found = vectors[vector.vector]
    if len(found) != length:
        raise CompareError(f"{path}: identification.compare_with.{key}: vector {vector.vector!r} holds {len(found)} "
                           f"values, the config's robot needs {length}")
    return found


def _fill(values: np.ndarray, names: tuple[str, ...], found: np.ndarray, groups: list[list[str]], path: str,
          key: str, allowed) -> None:
    """``values`` (in ``names``' order) from ``found``, group after group of named entries."""
    flat = [name for group in groups for name in group]
    for name in flat:
        value_name = name.split(".")[-1] if "." in name else name.split("_", 1)[0]
        if value_name not in allowed:
            raise CompareError(f"{path}: identification.compare_with.{key}.order: {value_name!r} is none of "
                               f"{sorted(allowed)}")
        if name not in names:
            raise CompareError(f"{path}: identification.compare_with.{key}.order: {value_name!r} has no place in "
                               f"the compared model (it holds {_kinds(names, allowed)} of them)")
    for name, value in zip(flat, found):
        values[names.index(name)] = value


def _kinds(names: tuple[str, ...], allowed) -> list[str]:
    """Which of the ``allowed`` kinds of value (``fv``, ``fc``, ``Ixx``, ...) the compared model holds."""
    return sorted({n.split(".")[-1] if "." in n else n.split("_", 1)[0] for n in names} & set(allowed))


def predicted_forces(compared: ComparedSet, prepared_Y: np.ndarray, per_amp: np.ndarray) -> np.ndarray:
    """(N, a) the compared set's forces on rows whose regressor of ``ComparedSet.model`` is
    ``prepared_Y`` (N, a, P), in the config's measure (:meth:`ComparedSet.force_factor` of the
    config's force per ampere ``per_amp`` (a,))."""
    return (prepared_Y @ compared.values) * compared.force_factor(per_amp)
