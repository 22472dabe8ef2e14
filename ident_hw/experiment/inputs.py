"""What the identification takes of a config, made once at the edge: :class:`IdentificationPlan`.

The config (:class:`ident_hw.config.Config`) is the file as written; the functions that prepare
recordings, fit the steps and judge the result take the parts they use of this plan instead:
the actuators as arrays (:class:`Axes`: scalings and limits, each (a,) in actuator order), the
filter inputs of each trajectory used (:class:`TrajectoryInputs`), the identification section,
the robot section (its model and friction model), the CAD and true parameter vectors. The plan
is frozen, its arrays read-only: a step cannot change what the next one sees.

    plan = identification_plan(config)            # raises ValueError without an identification section
    plan.axes.force_per_amp                        # (a,) N·m/A | N/A
    plan.filter_of("excitation", 250.0)           # FilterSettings of that trajectory's recording
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from drivers.profiles import AveragingFilter, get_profile
from ident_hw.config import ActuatorConfig, Config, IdentificationConfig, RobotConfig, TrajectoryConfig
from ident_hw.config.robots import initial_parameters, model_of, true_parameters
from ident_hw.config.to_drivers import axes_scaling
from ident_hw.config.to_identification import filter_settings
from ident_hw.config.trajectory import REST_TO_REST_KINDS
from ident_hw.filtering import POSITION_MARGIN, FilterSettings
from ident_hw.model.interface import RobotModel
from ident_hw.records import Thresholds

from .quality import thresholds_of
from .robot_trajectories import excitation_of


def _frozen(values: Sequence[float] | np.ndarray) -> np.ndarray:
    """A read-only float array of ``values``."""
    out = np.array(values, dtype=float)
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class Axes:
    """The robot's actuators as the identification and the readers of recordings see them, each
    array (a,) in actuator order, SI.

    ``names``, ``kinds`` (``revolute``, ``prismatic``); ``labels``: how a message names each
    (``node 3 (theta1)``); ``profiles``: each drive's profile (``epos2``, ``epos4``; None without
    a bus). Limits: ``position_low``, ``position_high`` (rad | m), ``velocity_limit`` (rad/s |
    m/s), ``acceleration_limit`` (rad/s² | m/s²), ``current_limit`` (A); scalings:
    ``force_per_amp`` (N·m/A | N/A: torque constant × gear, or over the screw lead) and
    ``counts_per_unit`` (encoder counts per rad | m)."""

    names: tuple[str, ...]
    kinds: tuple[str, ...]
    labels: tuple[str, ...]
    profiles: tuple[str | None, ...]
    position_low: np.ndarray
    position_high: np.ndarray
    velocity_limit: np.ndarray
    acceleration_limit: np.ndarray
    current_limit: np.ndarray
    force_per_amp: np.ndarray
    counts_per_unit: np.ndarray

    @classmethod
    def of(cls, actuators: Sequence[ActuatorConfig]) -> Axes:
        """The axes of a config's ``robot.actuators``."""
        scaling = axes_scaling(actuators)
        return cls(names=tuple(a.name for a in actuators), kinds=tuple(a.kind for a in actuators),
                   labels=tuple(f"node {a.node_id} ({a.name})" for a in actuators),
                   profiles=tuple(a.profile for a in actuators),
                   position_low=_frozen([a.limits.position[0] for a in actuators]),
                   position_high=_frozen([a.limits.position[1] for a in actuators]),
                   velocity_limit=_frozen([a.limits.velocity for a in actuators]),
                   acceleration_limit=_frozen([a.limits.acceleration for a in actuators]),
                   current_limit=_frozen([a.limits.current for a in actuators]),
                   force_per_amp=_frozen(scaling.force_per_amp), counts_per_unit=_frozen(scaling.counts_per_unit))

    def __len__(self) -> int:
        return len(self.names)

    @property
    def current_averaging(self) -> tuple[AveragingFilter, ...]:
        """Each drive's running average of the current (its drive generation's filter, what it
        streams as the averaged current)."""
        return tuple(get_profile(p).current_averaging for p in self.profiles)    # type: ignore[arg-type]


@dataclass(frozen=True)
class TrajectoryInputs:
    """What the identification takes of one trajectory of the config: its ``name`` and ``kind``,
    the ``bandwidth`` (Hz) of its motion (its ``bandwidth`` key, else the highest harmonic of a
    Fourier excitation, else the identification filter's) and how far above that band its
    positions are low-passed (``position_margin``,
    :attr:`ident_hw.filtering.FilterSettings.position_margin`)."""

    name: str
    kind: str
    bandwidth: float
    position_margin: float

    @property
    def standstill(self) -> bool:
        """A standstill: its recording gives each drive's current noise at rest."""
        return self.kind == "standstill"


@dataclass(frozen=True)
class IdentificationPlan:
    """The identification of a config, made once (:func:`identification_plan`): see the module
    docstring. ``source``: the config file (for messages); ``identification``: its section;
    ``robot``: its robot section (the model, the friction model); ``model``: the robot's model
    as configured (its friction constants left ``auto`` not yet chosen); ``initial``, ``truth``
    (n,): the CAD and, on the simulated rig, the true parameters in the model's order;
    ``trajectories``: the inputs of each trajectory of the config the identification uses (its
    steps', its validation's, the standstills); ``cycles_planned``: the set-points of each, for a
    recording that does not say how many it was to hold (absent: unknown)."""

    source: str
    axes: Axes
    identification: IdentificationConfig
    robot: RobotConfig
    model: RobotModel
    initial: np.ndarray
    truth: np.ndarray | None
    trajectories: Mapping[str, TrajectoryInputs]
    cycles_planned: Mapping[str, int] = field(default_factory=dict)

    @property
    def thresholds(self) -> Thresholds:
        """The quality verdict's limits (``identification.quality``)."""
        return thresholds_of(self.identification.quality)

    @property
    def needed(self) -> tuple[str, ...]:
        """The trajectories the identification needs a recording of: its steps', then its validation's."""
        ident = self.identification
        return tuple(dict.fromkeys([n for s in ident.steps for n in s.trajectories] + list(ident.validation)))

    @property
    def fitted(self) -> tuple[str, ...]:
        """The trajectories some step fits, in the steps' order."""
        return tuple(dict.fromkeys(t for s in self.identification.steps for t in s.trajectories))

    @property
    def standstills(self) -> tuple[str, ...]:
        """The standstill trajectories of the config, in its order."""
        return tuple(t.name for t in self.trajectories.values() if t.standstill)

    def inputs_of(self, name: str) -> TrajectoryInputs:
        """The inputs of trajectory ``name``; for a name the config does not list, the filter's
        own band and no position margin."""
        found = self.trajectories.get(name)
        if found is not None:
            return found
        margin = self.identification.filter.position_margin
        return TrajectoryInputs(name, "", self.identification.filter.bandwidth, 1.0 if margin is None else margin)

    def filter_of(self, name: str, sample_rate: float) -> FilterSettings:
        """The identification filter of trajectory ``name``'s recording sampled at ``sample_rate``
        (Hz), at its motion's band and position margin. Raises ValueError where the config's
        filter does not fit that rate (a cut-off above its Nyquist frequency)."""
        inputs = self.inputs_of(name)
        return filter_settings(self.identification.filter, sample_rate, inputs.bandwidth, inputs.position_margin)


def trajectory_inputs(tcfg: TrajectoryConfig, ident: IdentificationConfig) -> TrajectoryInputs:
    """The identification's inputs of the config's trajectory ``tcfg`` (:class:`TrajectoryInputs`;
    ``ident``: the identification section): its ``bandwidth``
    key, else a Fourier excitation's highest harmonic, else the identification filter's band; its
    position margin: ``identification.filter.position_margin`` where given, else
    :data:`ident_hw.filtering.POSITION_MARGIN` for the rest-to-rest kinds
    (:data:`ident_hw.config.trajectory.REST_TO_REST_KINDS`), whose force near the band edge would
    otherwise be biased, and 1 (one cut-off) for band-limited motions."""
    if tcfg.bandwidth is not None:
        bandwidth = tcfg.bandwidth
    elif tcfg.kind == "fourier":
        bandwidth = excitation_of(tcfg).bandwidth
    else:
        bandwidth = ident.filter.bandwidth
    margin = ident.filter.position_margin
    if margin is None:
        margin = POSITION_MARGIN if tcfg.kind in REST_TO_REST_KINDS else 1.0
    return TrajectoryInputs(tcfg.name, tcfg.kind, bandwidth, margin)


def identification_plan(config: Config, cycles_planned: Mapping[str, int] | None = None) -> IdentificationPlan:
    """The identification plan of ``config`` (see the module docstring); ``cycles_planned``: the
    set-points of trajectories whose recordings do not say (the runner's :func:`ident_hw.experiment.plan.plan` counts them).

    Raises:
        ValueError: the config has no identification section (naming the file).
    """
    ident = config.identification
    if ident is None:
        raise ValueError(f"{config.source}: identification: missing section")
    listed = {t.name for t in config.trajectories}
    used = [n for n in dict.fromkeys([n for s in ident.steps for n in s.trajectories] + list(ident.validation))
            if n in listed]
    used += [t.name for t in config.trajectories if t.kind == "standstill" and t.name not in used]
    model = model_of(config.robot)
    truth = true_parameters(config, model)
    return IdentificationPlan(source=config.source, axes=Axes.of(config.robot.actuators), identification=ident,
                              robot=config.robot, model=model, initial=_frozen(initial_parameters(config.robot)),
                              truth=None if truth is None else _frozen(truth), cycles_planned=dict(cycles_planned or {}),
                              trajectories={t.name: trajectory_inputs(t, ident)
                                            for t in config.trajectories if t.name in used})

