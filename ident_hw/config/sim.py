"""The ``sim`` section: the simulated rig's true parameters, drives, noise and injected fault."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from drivers.cia import NODE_ID_MAX, NODE_ID_MIN

from .robot_3prrr import InertialConfig
from .robot_delta import DeltaParametersConfig
from .robot_described import ParameterSetConfig
from .schema import in_range, non_negative, positive, spec

#: the keys of ``sim`` that hold some robot kind's true parameters
TRUTH_KEYS = ("truth", "delta_truth", "parameters")


@dataclass(frozen=True)
class SimFaultConfig:
    """A drive fault the in-process simulated rig raises during a run (tests, demos): drive
    ``node_id`` sends EMCY ``code`` and goes to FAULT ``after`` s into trajectory ``trajectory``."""

    trajectory: str
    after: float = field(metadata=spec(non_negative, unit="s"))
    node_id: int = field(metadata=spec(in_range(NODE_ID_MIN, NODE_ID_MAX)))
    code: int = field(default=0x2310, metadata=spec(in_range(0x1000, 0xFFFF), doc="EMCY error code"))


class SeedStream(enum.IntEnum):
    """The random streams the config draws from ``sim.seed``, each its own
    (``numpy.random.default_rng([seed, stream])``, :meth:`rng`), apart from the rig's noise and
    frame losses (:class:`drivers.sim.rig.SimulatedRig`'s ``seed``). Their numbers are part of
    every simulated result: changing one changes the results of the same seed."""

    #: each simulated axis's encoder count-edge shift (``sim.encoder_edges: random``)
    ENCODER_EDGES = 2
    #: the factors of the true parameters drawn around the configured ones (``sim.perturb``)
    TRUTH_PERTURBATION = 3

    def rng(self, seed: int) -> np.random.Generator:
        """The generator of this stream of ``seed``."""
        return np.random.default_rng([seed, int(self)])


@dataclass(frozen=True)
class SimConfig:
    """The simulated rig: its TRUE parameters (unknown to the identification), its drives'
    position loops and the measurement noise (currents are reported in whole mA, positions in
    encoder counts, as by the real drives)."""

    truth: InertialConfig | None = field(default=None, metadata=spec(doc="the 3PRRR's true parameters"))
    delta_truth: DeltaParametersConfig | None = field(default=None, metadata=spec(doc="the Delta's true parameters"))
    parameters: ParameterSetConfig | None = field(default=None, metadata=spec(
        doc="a described robot's true parameters"))
    current_noise: float = field(default=0.0, metadata=spec(non_negative, unit="A", doc="Gaussian std"))
    bandwidth: float = field(default=20.0, metadata=spec(positive, unit="Hz", doc="position loops"))
    damping: float = field(default=1.0, metadata=spec(positive))
    max_substep: float | None = field(default=None, metadata=spec(
        in_range(1e-5, 0.01), unit="s", doc="integration step of the plant (Runge-Kutta, fourth order; default "
                                            "drivers.sim.plant.DEFAULT_MAX_SUBSTEP, 0.5 ms)"))
    brakes: bool = field(default=False, metadata=spec(
        doc="holding brakes: an axis whose drive is disabled stays where it stands (a robot carrying "
            "its weight, such as the Delta, does not fall when the drives are disabled)"))
    in_process: bool = True
    seed: int = 0
    encoder_edges: Literal["fixed", "random"] = field(default="fixed", metadata=spec(
        doc="where the encoders count: 'fixed' halfway between whole multiples of a count, 'random' moved by a "
            "fraction of a count per axis drawn from the seed (what differs between two rigs, or two homings of "
            "one; a study draws them per run)"))
    perturb: float = field(default=0.0, metadata=spec(
        in_range(0.0, 1.0), doc="the true parameters drawn around the configured ones: each body's inertial "
        "parameters (a described or Delta body: the names before the '.') scaled by one factor, every other "
        "parameter by its own, the factors exp(perturb * N(0, 1)) drawn from the seed (a study's --perturb); "
        "0: the configured truth"))
    fault: SimFaultConfig | None = None
