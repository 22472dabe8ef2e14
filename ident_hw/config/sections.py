"""The typed sections of an ident_hw config file (SI units everywhere: m, rad, s, kg, A, N).

Each section is a frozen dataclass read by :mod:`ident_hw.config.schema`; the comments in
``configs/*.yaml`` document the keys for a user. Sections know how to turn into the objects of
the other layers (model geometry and parameters, drive unit scaling).
"""

from __future__ import annotations

import dataclasses
import difflib
import fnmatch
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import can

import drivers.axis
import drivers.bus
from drivers.cia import NODE_ID_MAX, NODE_ID_MIN
from drivers.axis import HomingConfig
from drivers.units import PRISMATIC, REVOLUTE, AxisScaling
from ident_hw.identification.least_squares import POORLY_IDENTIFIED_PERCENT
import numpy as np

from ident_hw.model import Delta, DeltaGeometry, Geometry, InertialParams
from ident_hw.model.delta import BODY_PARAMS, BODIES, physical_parameters
from ident_hw.model.interface import POSITION_UNITS, RobotModel
from ident_hw.filtering import FilterSettings
from trajectories.feasibility import ActuatorLimits
from trajectories.feasibility import Limits as FeasibilityLimits

from .physical import PhysicalConfig, check_scales, drive_term, parameter_kind, parameter_scales
from .robots import COMMON_TRAJECTORY_KINDS, DescribedConfig, ParameterSetConfig, kind_of
from .schema import FieldError, in_range, non_negative, ordered_pair, positive, spec


def _plus_minus_one(value) -> None:
    if any(v not in (1, -1) for v in value):
        raise ValueError(f"expected +1 or -1 for each chain, got {list(value)}")


@dataclass(frozen=True)
class GeometryConfig:
    """Geometry of the 3PRRR, per ``docs/3prrr-model.md``."""

    l1: float = field(metadata=spec(positive, unit="m"))
    l2: float = field(metadata=spec(positive, unit="m"))
    s1: float = field(metadata=spec(non_negative, unit="m"))
    s2: float = field(metadata=spec(non_negative, unit="m"))
    h: float = field(metadata=spec(positive, unit="m"))
    a: float = field(metadata=spec(positive, unit="m"))
    gamma: tuple[float, float, float] = field(metadata=spec(unit="rad", angle=True))
    modes: tuple[int, int, int] = field(default=(1, 1, 1), metadata=spec(_plus_minus_one))

    def _check(self) -> None:
        if self.s1 > self.l1:
            raise FieldError("s1", f"expected s1 <= l1 = {self.l1} m, got {self.s1}")
        if self.s2 > self.l2:
            raise FieldError("s2", f"expected s2 <= l2 = {self.l2} m, got {self.s2}")

    def to_model(self) -> Geometry:
        return Geometry(l1=self.l1, l2=self.l2, s1=self.s1, s2=self.s2, h=self.h, a=self.a,
                        gamma=self.gamma, modes=self.modes)


@dataclass(frozen=True)
class InertialConfig:
    """Masses (kg), inertias about the centres of mass (kg·m²), friction per actuator."""

    m_c: float = field(metadata=spec(non_negative, unit="kg"))
    m_l1: float = field(metadata=spec(non_negative, unit="kg"))
    I_l1: float = field(metadata=spec(non_negative, unit="kg m^2"))
    m_l2: float = field(metadata=spec(non_negative, unit="kg"))
    I_l2: float = field(metadata=spec(non_negative, unit="kg m^2"))
    m_ee: float = field(metadata=spec(non_negative, unit="kg"))
    I_ee: float = field(metadata=spec(non_negative, unit="kg m^2"))
    f_v: tuple[float, float, float, float, float, float] = field(
        default=(0.0,) * 6, metadata=spec(non_negative, unit="N m s/rad | N s/m"))
    f_c: tuple[float, float, float, float, float, float] = field(
        default=(0.0,) * 6, metadata=spec(non_negative, unit="N m | N"))

    def to_model(self) -> InertialParams:
        return InertialParams(m_c=self.m_c, m_l1=self.m_l1, I_l1=self.I_l1, m_l2=self.m_l2,
                              I_l2=self.I_l2, m_ee=self.m_ee, I_ee=self.I_ee, f_v=self.f_v, f_c=self.f_c)


@dataclass(frozen=True)
class DeltaGeometryConfig:
    """Geometry of the Delta, per ``docs/delta-model.md`` (defaults: the SVD-DLS paper's Table 1)."""

    L1: float = field(default=DeltaGeometry.L1, metadata=spec(positive, unit="m", doc="upper arm"))
    L2: float = field(default=DeltaGeometry.L2, metadata=spec(positive, unit="m", doc="parallelogram rods"))
    R: float = field(default=DeltaGeometry.R, metadata=spec(positive, unit="m", doc="radius of the actuated joints"))
    r: float = field(default=DeltaGeometry.r, metadata=spec(positive, unit="m", doc="radius of the platform joints"))
    psi: tuple[float, float, float] = field(default=DeltaGeometry.psi, metadata=spec(
        unit="rad", angle=True, doc="azimuths of the three limbs"))

    def to_model(self) -> DeltaGeometry:
        return DeltaGeometry(L1=self.L1, L2=self.L2, R=self.R, r=self.r, psi=self.psi)


@dataclass(frozen=True)
class DeltaParametersConfig:
    """The Delta's 79 parameters: the nominal bodies of its geometry (``docs/delta-model.md``)
    with ``factors`` applied by name (``plat.m: 1.2`` = 20 % heavier), and the drive terms per arm."""

    fv: tuple[float, float, float] = field(default=(0.0,) * 3, metadata=spec(non_negative, unit="N m s/rad"))
    fc: tuple[float, float, float] = field(default=(0.0,) * 3, metadata=spec(non_negative, unit="N m"))
    Jm: tuple[float, float, float] = field(default=(0.0,) * 3, metadata=spec(
        non_negative, unit="kg m^2", doc="rotor inertia reflected through the gear"))
    factors: dict[str, float] = field(default_factory=dict)

    def _check(self) -> None:
        bodies = {f"{b}.{p}" for b in BODIES for p in BODY_PARAMS}
        for name in self.factors:
            if name not in bodies:
                raise FieldError(f"factors.{name}", "unknown body parameter; expected <body>.<parameter>, "
                                 f"bodies {list(BODIES)}, parameters {list(BODY_PARAMS)}")

    def vector(self, geometry: DeltaGeometry) -> np.ndarray:
        """(79,) in the order of :data:`ident_hw.model.delta.PARAM_NAMES`."""
        pi = physical_parameters(geometry)
        names = Delta.parameter_names
        for name, factor in self.factors.items():
            pi[names.index(name)] *= factor
        pi[-9:] = [*self.fv, *self.fc, *self.Jm]
        return pi


@dataclass(frozen=True)
class DeltaConfig:
    """The Delta: geometry and CAD parameters (the start and reference of the identification)."""

    geometry: DeltaGeometryConfig = DeltaGeometryConfig()
    cad: DeltaParametersConfig = DeltaParametersConfig()


@dataclass(frozen=True)
class LimitsConfig:
    """Joint-side limits of one actuator: rad / m, rad/s / m/s, rad/s² / m/s², motor current A."""

    position: tuple[float, float] = field(metadata=spec(ordered_pair, unit="rad | m"))
    velocity: float = field(metadata=spec(positive, unit="rad/s | m/s"))
    acceleration: float = field(metadata=spec(positive, unit="rad/s^2 | m/s^2"))
    current: float = field(metadata=spec(positive, unit="A"))
    following_error: float = field(metadata=spec(positive, unit="rad | m"))


@dataclass(frozen=True)
class ActuatorConfig:
    """One motor + drive, in the robot's actuator order (the 3PRRR: theta1..3, zeta1..3)."""

    name: str
    kind: Literal["revolute", "prismatic"]
    node_id: int = field(metadata=spec(in_range(NODE_ID_MIN, NODE_ID_MAX)))
    profile: Literal["epos2", "epos4"]
    torque_constant: float = field(metadata=spec(positive, unit="N m/A"))
    counts_per_turn: int = field(metadata=spec(positive, doc="quadrature counts per motor turn"))
    limits: LimitsConfig
    homing: HomingConfig
    gear_ratio: float = field(default=1.0, metadata=spec(positive, doc="motor turns per joint turn"))
    screw_lead: float | None = field(default=None, metadata=spec(positive, unit="m per motor turn"))
    product_code: int | None = field(default=None, metadata=spec(non_negative, doc="expected 0x1018:02"))
    object_dictionary: str | None = field(default=None, metadata=spec(
        doc="the drive's EDS or DCF (maxon's, or saved from the drive), relative to the config file; "
            "default: the built-in dictionary of the profile"))
    joint: str | None = field(default=None, metadata=spec(
        doc="a described robot's joint this actuator drives (default: its name)"))

    def _check(self) -> None:
        if self.kind == PRISMATIC and self.screw_lead is None:
            raise FieldError("screw_lead", "missing key: a prismatic actuator needs screw_lead (m per motor turn)")
        if self.kind == REVOLUTE and self.screw_lead is not None:
            raise FieldError("screw_lead", "a revolute actuator has no screw_lead")

    def scaling(self) -> AxisScaling:
        """Drive-unit ↔ SI scaling of this axis."""
        return AxisScaling(kind=self.kind, counts_per_turn=self.counts_per_turn,
                           torque_constant=self.torque_constant, gear_ratio=self.gear_ratio,
                           screw_lead=self.screw_lead)

    def to_driver(self, base: Path | None = None,
                  current: str = drivers.axis.INSTANTANEOUS) -> drivers.axis.AxisConfig:
        """The drive driver's axis settings (SI); ``base``: the folder ``object_dictionary`` is
        relative to (the config file's); ``current``: the motor current it streams
        (``bus.current``)."""
        od_file = self.object_dictionary
        if od_file is not None and base is not None:
            od_file = str(Path(base) / od_file)
        return drivers.axis.AxisConfig(
            name=self.name, node_id=self.node_id, profile=self.profile, scaling=self.scaling(),
            position_min=self.limits.position[0], position_max=self.limits.position[1],
            max_velocity=self.limits.velocity, max_current=self.limits.current,
            following_error_window=self.limits.following_error, product_code=self.product_code,
            homing=self.homing, object_dictionary=od_file, current=current)


@dataclass(frozen=True)
class SafetyConfig:
    """Thresholds of the feasibility check: distance to parallel and serial singularities."""

    max_cond_A: float = field(default=50.0, metadata=spec(positive))
    min_serial_margin: float = field(default=0.1, metadata=spec(in_range(0.0, 1.0),
                                     doc="smallest |sin(beta_i - theta_i)|"))


@dataclass(frozen=True)
class RobotConfig:
    """The rig: which robot (``kind``, a kind of :mod:`ident_hw.config.robots`), its model's
    settings and its actuators.

    ``3prrr``: ``geometry``, carriage ``stroke``, ``cad`` values, ``safety`` margins and six
    actuators theta1..3, zeta1..3. ``delta``: the ``delta`` section (geometry, CAD parameters)
    and three revolute actuators q1..3. ``described``: the ``described`` section (the
    description file, home, CAD parameters) and one actuator per driven joint.
    """

    actuators: tuple[ActuatorConfig, ...]
    kind: Literal["3prrr", "delta", "described"] = "3prrr"
    geometry: GeometryConfig | None = None
    stroke: float | None = field(default=None, metadata=spec(positive, unit="m", doc="carriage travel +- stroke"))
    cad: InertialConfig | None = None
    delta: DeltaConfig | None = None
    described: DescribedConfig | None = None
    safety: SafetyConfig = SafetyConfig()
    coulomb_width: float = field(default=1e-3, metadata=spec(positive, unit="rad/s | m/s"))

    def to_model(self) -> RobotModel:
        """The robot's model (:class:`~ident_hw.model.interface.RobotModel`), a new one per call."""
        return kind_of(self).model(self)

    def initial_parameters(self) -> np.ndarray:
        """The CAD values (n,) in the order of the model's ``parameter_names``."""
        return kind_of(self).initial(self)

    def actuator_limits(self) -> ActuatorLimits:
        """Every actuator's position range, speed and acceleration limits, for
        :func:`trajectories.feasibility.check_actuator_limits`."""
        acts = self.actuators
        return ActuatorLimits(names=tuple(a.name for a in acts),
                              low=np.array([a.limits.position[0] for a in acts]),
                              high=np.array([a.limits.position[1] for a in acts]),
                              speed=np.array([a.limits.velocity for a in acts]),
                              accel=np.array([a.limits.acceleration for a in acts]),
                              units=tuple(POSITION_UNITS[a.kind] for a in acts))

    def feasibility_limits(self) -> FeasibilityLimits:
        """Limits for :func:`trajectories.feasibility.check_trajectory` of the 3PRRR (the tightest
        axis of each kind)."""
        rev, pri = self.actuators[:3], self.actuators[3:]
        return FeasibilityLimits(
            carriage_stroke=self.stroke,
            carriage_speed=min(a.limits.velocity for a in pri),
            carriage_accel=min(a.limits.acceleration for a in pri),
            revolute_speed=min(a.limits.velocity for a in rev),
            revolute_accel=min(a.limits.acceleration for a in rev),
            min_serial_margin=self.safety.min_serial_margin,
            max_cond_A=self.safety.max_cond_A)

    def _check(self) -> None:
        kind = kind_of(self)
        for key in ("geometry", "stroke", "cad", "delta", "described"):
            if getattr(self, key) is not None and key not in kind.sections:
                raise FieldError(key, f"belongs to another robot than robot.kind {self.kind!r} "
                                      f"(its sections: {', '.join(kind.sections)})")
        kind.validate(self)
        names, kinds = kind.actuators(self)
        if len(self.actuators) != len(names):
            raise FieldError("actuators", f"expected {len(names)} actuators ({', '.join(names)}), got {len(self.actuators)}")
        for i, (act, expected) in enumerate(zip(self.actuators, kinds)):
            if act.kind != expected:
                raise FieldError(f"actuators[{i}].kind",
                                 f"actuator {i} ({names[i]}) must be {expected!r}, got {act.kind!r}")
        seen: dict[int, int] = {}
        for i, act in enumerate(self.actuators):
            if act.node_id in seen:
                raise FieldError(f"actuators[{i}].node_id",
                                 f"node id {act.node_id} is already used by actuators[{seen[act.node_id]}]")
            seen[act.node_id] = i


def _python_can_interface(name: str) -> None:
    """An interface name python-can knows (``can.interfaces.VALID_INTERFACES``)."""
    if name not in can.interfaces.VALID_INTERFACES:
        close = difflib.get_close_matches(name, sorted(can.interfaces.VALID_INTERFACES), n=1)
        hint = f"did you mean {close[0]!r}?" if close else \
            f"python-can has {', '.join(sorted(can.interfaces.VALID_INTERFACES))}"
        raise ValueError(f"python-can has no interface {name!r}; {hint}")


@dataclass(frozen=True)
class BusConfig:
    """The CAN bus (python-can) and the SYNC rate of the cyclic exchange."""

    interface: str = field(metadata=spec(_python_can_interface, doc="a python-can interface name"))
    channel: str
    bitrate: int = field(default=1_000_000, metadata=spec(positive, unit="bit/s"))
    sync_rate: float = field(default=250.0, metadata=spec(in_range(1.0, 2000.0), unit="Hz"))
    sdo_timeout: float = field(default=0.5, metadata=spec(positive, unit="s"))
    heartbeat: float = field(default=0.1, metadata=spec(positive, unit="s"))
    heartbeat_timeout: float | None = field(default=None, metadata=spec(
        positive, unit="s", doc="consumer heartbeat timeout on both sides (default 3.5 heartbeat periods)"))
    bring_up_timeout: float = field(default=5.0, metadata=spec(
        positive, unit="s", doc="time for every drive to answer and reach PRE-OPERATIONAL at bring-up"))
    sync: Literal["periodic", "lockstep"] | None = field(default=None, metadata=spec(
        doc="SYNC producer: 'periodic' (real drives) or 'lockstep' (the simulated rig: SYNC k+1 once "
            "cycle k is in, simulated time = SYNC count x period); default lockstep against the "
            "simulated rig, periodic otherwise"))
    lockstep_timeout: float = field(default=10.0, metadata=spec(
        positive, unit="s", doc="wall-clock time a lockstep cycle may take before it is a fault"))
    current: Literal["instantaneous", "averaged"] = field(default="instantaneous", metadata=spec(
        doc="the motor current TPDO1 carries: 'instantaneous' (the drive's current actual value, sampled at "
            "each SYNC: EPOS4 0x30D1:02, EPOS2 0x6078) or 'averaged' (its running 50 Hz first-order low-pass: "
            "EPOS4 0x30D1:01, EPOS2 0x2027; the identification then filters the regressor by the same filter)"))

    def to_driver(self, ignore_config: bool = True) -> drivers.bus.BusConfig:
        """python-can settings of the bus (``ignore_config``: ignore the user's python-can files)."""
        bitrate = None if self.interface == "virtual" else self.bitrate
        return drivers.bus.BusConfig(interface=self.interface, channel=self.channel, bitrate=bitrate,
                                     ignore_config=ignore_config)

    @property
    def is_local(self) -> bool:
        """True for buses that cannot reach hardware (:func:`drivers.bus.is_local`)."""
        return drivers.bus.is_local(self.interface, self.channel)


@dataclass(frozen=True)
class SimFaultConfig:
    """A drive fault the in-process simulated rig raises during a run (tests, demos): drive
    ``node_id`` sends EMCY ``code`` and goes to FAULT ``after`` s into trajectory ``trajectory``."""

    trajectory: str
    after: float = field(metadata=spec(non_negative, unit="s"))
    node_id: int = field(metadata=spec(in_range(NODE_ID_MIN, NODE_ID_MAX)))
    code: int = field(default=0x2310, metadata=spec(in_range(0x1000, 0xFFFF), doc="EMCY error code"))


#: the keys of ``sim`` that hold some robot kind's true parameters
TRUTH_KEYS = ("truth", "delta_truth", "parameters")


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
    fault: SimFaultConfig | None = None

    def encoder_edge_counts(self, axes: int) -> np.ndarray:
        """(axes,) counts: each axis's count-edge shift (:attr:`encoder_edges`)."""
        if self.encoder_edges == "fixed":
            return np.zeros(axes)
        return np.random.default_rng([self.seed, 2]).uniform(-0.5, 0.5, axes)


@dataclass(frozen=True)
class PayloadConfig:
    """A payload the in-process simulated rig takes on ``after`` s into its trajectory (mass and
    inertia about the end-effector point, added to the true ``m_ee`` and ``I_ee``) and drops at
    the trajectory's end: what the online estimators must track."""

    after: float = field(metadata=spec(non_negative, unit="s"))
    mass: float = field(metadata=spec(positive, unit="kg"))
    inertia: float = field(default=0.0, metadata=spec(non_negative, unit="kg m^2"))


@dataclass(frozen=True)
class TrajectoryConfig:
    """One trajectory of the campaign (generators of :mod:`trajectories`).

    ``kind``: ``carriage_sweep`` (rotary actuators held, each carriage 0 → -size → +size → 0,
    then the three together), ``square`` (carriages held, side ``size``, rotated by
    ``rotation``), ``triangle`` (the paper's validation triangle, carriages scheduled for
    singularity margins), ``fourier`` (an optimised Fourier excitation of all the base
    parameters, :class:`trajectories.FourierExcitation`; ``path`` to its JSON coefficients,
    default the excitation optimised for the nominal rig that ships with ``trajectories``),
    ``file`` (a saved trajectory, CSV or NPZ). ``path`` is relative to the config file.
    Timing of the generated paths is rest-to-rest at ``speed_scale`` × the actuator limits,
    with ``dwell`` s at rest at each waypoint (the Fourier excitation and a file have their own
    timing); the motion is repeated ``cycles`` times. ``bandwidth`` (Hz), the highest frequency
    the motion has, sets the identification filter of this trajectory (default: the highest
    harmonic of a Fourier excitation, else ``identification.filter.bandwidth``).
    The Delta's paths (the SVD-DLS paper, :mod:`trajectories.delta_paper`): ``delta_training``
    (Table 2), ``delta_verification`` (eq. 60), ``delta_held_arm`` (eq. 60 with arm 3 held), each
    ``duration`` s long, its angles scaled by ``amplitude`` (one factor, or one per arm), faded
    in and out over ``fade`` s from and back to the arms at rest.
    A described robot's excitation (:func:`trajectories.joint_space.joint_excitation`):
    ``joint_excitation``, ``duration`` s of ``harmonics`` sines per actuator up to ``bandwidth``
    Hz (default: ``identification.filter.bandwidth``) about home, phases and frequencies drawn from ``seed``, fitted to 0.8 of
    each actuator's limits and scaled by ``amplitude`` (one factor, or one per actuator).
    ``online_only``: streamed only for the online estimators (``ident-hw online``, or ``run``
    with ``identification.online.in_run``), after the others; otherwise ``run`` leaves it out. ``payload``: on the in-process simulated rig, a payload added during this trajectory
    (:class:`PayloadConfig`), e.g. on an ``online_only`` one for the online estimators to track.
    """

    name: str
    kind: Literal["carriage_sweep", "square", "triangle", "fourier", "file",
                  "delta_training", "delta_verification", "delta_held_arm", "joint_excitation"]
    size: float | None = field(default=None, metadata=spec(positive, unit="m"))
    rotation: float = field(default=0.0, metadata=spec(unit="rad", angle=True))
    speed_scale: float = field(default=1.0, metadata=spec(in_range(0.01, 1.0)))
    dwell: float = field(default=0.0, metadata=spec(non_negative, unit="s"))
    cycles: int = field(default=1, metadata=spec(in_range(1, 1000)))
    path: str | None = None
    bandwidth: float | None = field(default=None, metadata=spec(positive, unit="Hz"))
    duration: float | None = field(default=None, metadata=spec(positive, unit="s"))
    fade: float = field(default=1.0, metadata=spec(non_negative, unit="s"))
    amplitude: float | tuple[float, ...] = field(default=1.0, metadata=spec(in_range(0.01, 10.0)))
    online_only: bool = False
    payload: PayloadConfig | None = None
    harmonics: int = field(default=5, metadata=spec(in_range(1, 50)))
    seed: int = 0

    def _check(self) -> None:
        if (self.kind.startswith("delta_") or self.kind == "joint_excitation") and self.duration is None:
            raise FieldError("duration", f"missing key: a {self.kind!r} trajectory needs duration (s)")
        if self.kind == "file" and self.path is None:
            raise FieldError("path", "missing key: a 'file' trajectory needs path")
        if self.kind not in ("file", "fourier") and self.path is not None:
            raise FieldError("path", f"a {self.kind!r} trajectory is generated: only 'file' and 'fourier' "
                                     "trajectories have a path")
        if isinstance(self.amplitude, tuple) and not (self.kind.startswith("delta_") and len(self.amplitude) == 3
                                                      or self.kind == "joint_excitation"):
            raise FieldError("amplitude", f"one amplitude per arm is for the Delta's three arms (delta_* kinds) "
                                          f"and a joint_excitation's actuators, got {len(self.amplitude)} for a "
                                          f"{self.kind!r} trajectory")
        if self.kind in ("carriage_sweep", "square") and self.size is None:
            raise FieldError("size", f"missing key: a {self.kind!r} trajectory needs size (m)")


@dataclass(frozen=True)
class FilterConfig:
    """Data preparation: zero-phase Butterworth low-pass of the positions, parallel decimation.

    Defaults follow the sample rate and the motion ``bandwidth``
    (:meth:`ident_hw.filtering.FilterSettings.for_sample_rate`); ``cutoff`` and ``decimation``
    override them.
    """

    bandwidth: float = field(default=5.0, metadata=spec(positive, unit="Hz"))
    order: int = field(default=4, metadata=spec(in_range(1, 12)))
    cutoff: float | None = field(default=None, metadata=spec(positive, unit="Hz"))
    decimation: int | None = field(default=None, metadata=spec(in_range(1, 100)))

    def settings(self, sample_rate: float, bandwidth: float | None = None) -> FilterSettings:
        """The filter settings for data sampled at ``sample_rate`` (Hz), for a motion of
        ``bandwidth`` Hz (default :attr:`bandwidth`)."""
        base = FilterSettings.for_sample_rate(sample_rate, bandwidth or self.bandwidth, self.order)
        overrides = {k: v for k, v in (("cutoff_hz", self.cutoff), ("decimation", self.decimation)) if v is not None}
        return dataclasses.replace(base, **overrides)


@dataclass(frozen=True)
class StepConfig:
    """One identification step: which recorded trajectories identify which parameters.

    ``sqp``: bounded fit of the listed parameters, the others held at their current values
    (the 3PRRR paper); the result is carried into the next steps. ``wls``/``ols``: least squares of the
    base parameters of the listed ones (the SVD-DLS paper; the others held), with their standard
    deviations (the power-model paper); reported beside the physical parameters, not carried on (a base
    parameter can group several physical ones). At most one step is ``wls``/``ols``.
    """

    name: str
    trajectories: tuple[str, ...]
    parameters: tuple[str, ...] = field(metadata=spec(
        doc="parameter names or shell-style patterns of them (leg?_rod.I*), or [all]: every parameter of the model"))
    method: Literal["sqp", "ols", "wls"] = "sqp"

    def parameter_names(self, names: tuple[str, ...]) -> tuple[str, ...]:
        """The step's parameters among the model's ``names``, in the model's order where a pattern
        (``*``, ``?``, ``[...]``) names several (``[all]``: every one); a name that is neither a
        parameter nor a pattern matching one stays as it is (the config check refuses it)."""
        if self.parameters == ("all",):
            return tuple(names)
        out: list[str] = []
        for entry in self.parameters:
            matched = [n for n in names if fnmatch.fnmatchcase(n, entry)] if entry not in names else [entry]
            for name in matched or [entry]:
                if name not in out:
                    out.append(name)
        return tuple(out)



@dataclass(frozen=True)
class OnlineConfig:
    """The online estimators (SVD-DLS, beside RLS and damped RLS on the same data).

    They work on parameters divided by their ``scales`` and on forces divided by the noise of
    the outputs, so that ``threshold`` means the same for every direction (100 ⇔ a relative
    standard deviation of 10 % of the scale). Scales: ``scales`` per parameter name, friction
    kind (``fv_zeta`` ...) or drive term (``fv``), else the magnitude of the CAD value, else
    :data:`FRICTION_SCALES`, else (a body parameter) the largest CAD magnitude of its family
    (:data:`BODY_PARAMETER_FAMILIES`).
    """

    forgetting: float = field(default=0.999, metadata=spec(in_range(0.5, 1.0)))
    threshold: float = field(default=100.0, metadata=spec(
        positive, doc="eigenvalue threshold of the scaled information matrix: 100 = 10 % relative std"))
    output_noise: float = field(default=0.001, metadata=spec(
        positive, unit="A", doc="standard deviation of a motor current after the parallel filter and decimation "
                                "(1 mA: the drives' resolution)"))
    scales: dict[str, float] = field(default_factory=dict)
    damping: float = field(default=100.0, metadata=spec(
        positive, doc="regularisation of the damped-RLS baseline, in the scaled units of the threshold"))
    in_run: bool = field(default=False, metadata=spec(
        doc="run the estimators in `ident-hw run` too, as `ident-hw online` does (the online_only "
            "trajectories streamed after the others, the comparison printed and in the report)"))

    def _check(self) -> None:
        check_scales(self.scales)

    def parameter_scales(self, names, cad) -> tuple[float, ...]:
        """(n,) the scale of every parameter ``names`` (n,) with CAD values ``cad`` (see the class)."""
        return parameter_scales(names, cad, self.scales, "identification.online.scales")


@dataclass(frozen=True)
class QualityConfig:
    """Thresholds of the quality verdict (:mod:`ident_hw.experiment.quality`) of every run and
    identify: a result whose data or fit miss one ends ``degraded`` (with the reasons), not
    ``complete``."""

    min_coverage: float = field(default=1.0, metadata=spec(
        in_range(0.0, 1.0), doc="fraction of each trajectory's set-points its recording must hold"))
    min_valid_fraction: float = field(default=0.9, metadata=spec(
        in_range(0.0, 1.0), doc="fraction of complete cycles (every frame of every drive) per trajectory"))
    max_gap: float = field(default=0.2, metadata=spec(
        positive, unit="s", doc="longest stretch of a trajectory without a complete cycle"))
    max_condition: float = field(default=1e4, metadata=spec(
        positive, doc="condition number of each step's regressor, columns scaled to unit RMS (the paper's "
                      "squares give 2.2e3 for the link step: its inertias then come out poorly identified)"))
    max_d_tau: float = field(default=10.0, metadata=spec(
        positive, unit="%", doc="force prediction error d_tau of the result on each validation trajectory "
                                "(on each identification one when there is none)"))
    max_disagreement: float = field(default=10.0, metadata=spec(
        positive, unit="%", doc="difference of the step-by-step and base-parameter force predictions, "
                                "relative to the measured forces, on the trajectories max_d_tau judges"))
    min_well_identified: int = field(default=1, metadata=spec(
        non_negative, doc="fitted parameters (physical or base) with %sigma <= rel_sigma_threshold"))
    max_force_lag: float = field(default=5e-4, metadata=spec(
        positive, unit="s", doc="delay of an axis's measured forces behind the model's (least squares over all "
                                "fitted trajectories): beyond it the data and the model disagree in time (a current "
                                "averaged by the drive identified as instantaneous: bus.current)"))
    max_axis_gain_spread: float = field(default=2.0, metadata=spec(
        positive, unit="%", doc="an axis's forces against the model's prediction (least-squares gain over all "
                                "fitted trajectories), minus the median of the other axes with the same drive: "
                                "beyond it, that axis's torque constant, gear or lead is likely off"))
    max_axis_residual_ratio: float = field(default=3.0, metadata=spec(
        positive, doc="an axis's force residual (RMS, on any fitted trajectory) over the median of those of "
                      "the other axes with the same drive: above it the data contradict the model on that "
                      "axis (its torque constant, gear, lead or friction model)"))


@dataclass(frozen=True)
class IdentificationConfig:
    """Steps run in order (each fixes the parameters it identifies), validation trajectories,
    the SQP bounds ``[min, max]`` per parameter, the %σ above which an estimate is reported
    as poorly identified on its data, and the thresholds of the quality verdict."""

    steps: tuple[StepConfig, ...]
    validation: tuple[str, ...] = ()
    rel_sigma_threshold: float = field(default=POORLY_IDENTIFIED_PERCENT, metadata=spec(
        positive, unit="%", doc="estimates with a larger relative standard deviation are poorly identified"))
    min_speed: float = field(default=0.02, metadata=spec(
        in_range(0.0, 0.5), doc="an axis moving slower than this fraction of its velocity limit gives no row to the "
                                "fits: the Coulomb term sign(qdot) does not describe friction near rest"))
    encoder_draws: int = field(default=8, metadata=spec(
        in_range(0, 1000), doc="draws of the recordings read again by encoders whose count edges are moved by a "
                               "random fraction of a count; the spread of their estimates joins every sigma "
                               "(the encoders' resolution, whose errors repeat where the motion repeats); 0: "
                               "the least-squares statistics alone"))
    bounds: dict[str, tuple[float, float]] = field(default_factory=dict)
    filter: FilterConfig = FilterConfig()
    online: OnlineConfig = OnlineConfig()
    quality: QualityConfig = QualityConfig()
    physical: PhysicalConfig = PhysicalConfig()
    compare_models: bool = field(default=False, metadata=spec(
        doc="the power-model paper's comparison: the least-squares step's base parameters by the dynamic, "
            "power and energy models on the same recordings and filters (robots with an energy regressor)"))

    def _check(self) -> None:
        least_squares = [i for i, s in enumerate(self.steps) if s.method != "sqp"]
        if len(least_squares) > 1:
            raise FieldError(f"steps[{least_squares[1]}].method",
                             f"only one step may fit base parameters by least squares (steps "
                             f"{[self.steps[i].name for i in least_squares]} are 'wls'/'ols')")
        for name, pair in self.bounds.items():
            if not pair[0] <= pair[1]:
                raise FieldError(f"bounds.{name}", f"expected [min, max] with min <= max, got {list(pair)}")


@dataclass(frozen=True)
class OutputConfig:
    """Where results go (relative paths are relative to the working directory)."""

    dir: str = "results"
    raw_log: Literal[".log", ".asc", ".blf"] = ".log"


@dataclass(frozen=True)
class Config:
    """A whole config file. Only ``robot`` is required; a campaign also needs ``bus``,
    ``trajectories`` and ``identification``."""

    robot: RobotConfig
    bus: BusConfig | None = None
    sim: SimConfig | None = None
    trajectories: tuple[TrajectoryConfig, ...] = ()
    identification: IdentificationConfig | None = None
    output: OutputConfig = OutputConfig()
    source: str = field(default="", init=False, compare=False)

    def _check(self) -> None:
        model = self.robot.to_model()           # once: a described robot's is read from its file
        self._check_parameter_names(model.parameter_names)
        kind = kind_of(self.robot)
        self._check_sim(model, kind)
        names = self._check_trajectory_names()
        if self.bus is not None and self.bus.sync == "lockstep" and not self.simulated:
            raise FieldError("bus.sync", f"lockstep paces the SYNC by the simulated rig's answers; "
                             f"{self.bus.interface}:{self.bus.channel} may carry real drives, which "
                             f"need 'periodic'" + ("" if self.sim is not None else " (no sim: section)"))
        self._check_fault(names)
        self._check_trajectory_kinds(kind)
        if self.identification is not None and self.identification.compare_models:
            if not any(s.method != "sqp" for s in self.identification.steps):
                raise FieldError("identification.compare_models", "needs a step that fits base parameters by "
                                 "least squares (method 'wls' or 'ols')")
            from ident_hw.identification.model_comparison import supports_energy_models
            why = supports_energy_models(model)
            if why:
                raise FieldError("identification.compare_models", why)
        for i, t in enumerate(self.trajectories):
            if t.payload is not None and (self.sim is None or not self.sim.in_process):
                raise FieldError(f"trajectories[{i}].payload", "a payload is put on by the in-process simulated "
                                 "rig (sim.in_process: true)")

    def _check_sim(self, model: RobotModel, kind) -> None:
        """The sim section's truth is the robot kind's (``sim.<truth key>``), and its parameters the model's."""
        if self.sim is None:
            return
        key = kind.truth_key
        if getattr(self.sim, key) is None:
            raise FieldError(f"sim.{key}", f"missing key: the simulated {self.robot.kind}'s true parameters")
        for other in TRUTH_KEYS:
            if other != key and getattr(self.sim, other) is not None:
                raise FieldError(f"sim.{other}", f"belongs to another robot than robot.kind {self.robot.kind!r} "
                                 f"(its true parameters are sim.{key})")
        if self.sim.parameters is not None:
            try:
                self.sim.parameters.check_against(model)
            except FieldError as exc:
                raise FieldError(f"sim.parameters.{exc.key}", exc.message) from None

    def _check_trajectory_names(self) -> dict[str, int]:
        """Every trajectory name once, and every one the identification names defined; returns
        name -> index."""
        names: dict[str, int] = {}
        for i, t in enumerate(self.trajectories):
            if t.name in names:
                raise FieldError(f"trajectories[{i}].name", f"trajectory name {t.name!r} is used twice")
            names[t.name] = i
        if self.identification is not None:
            for s, step in enumerate(self.identification.steps):
                for j, t in enumerate(step.trajectories):
                    if t not in names:
                        raise FieldError(f"identification.steps[{s}].trajectories[{j}]",
                                         f"no trajectory named {t!r}; defined: {list(names)}")
            for j, t in enumerate(self.identification.validation):
                if t not in names:
                    raise FieldError(f"identification.validation[{j}]",
                                     f"no trajectory named {t!r}; defined: {list(names)}")
        return names

    def _check_fault(self, names: dict[str, int]) -> None:
        """An injected fault names a trajectory and an actuator of this config, on the in-process rig."""
        fault = self.sim.fault if self.sim is not None else None
        if fault is None:
            return
        if fault.trajectory not in names:
            raise FieldError("sim.fault.trajectory", f"no trajectory named {fault.trajectory!r}; "
                             f"defined: {list(names)}")
        if fault.node_id not in [a.node_id for a in self.robot.actuators]:
            raise FieldError("sim.fault.node_id", f"no actuator with node id {fault.node_id}")
        if not self.sim.in_process:
            raise FieldError("sim.fault", "fault injection needs the in-process rig (sim.in_process: true)")

    def _check_trajectory_kinds(self, kind) -> None:
        """Every trajectory of a kind the robot has, a joint excitation's amplitudes one per actuator."""
        for i, t in enumerate(self.trajectories):
            if t.kind not in kind.trajectory_kinds + COMMON_TRAJECTORY_KINDS:
                raise FieldError(f"trajectories[{i}].kind", f"a {t.kind!r} trajectory is not one of the "
                                 f"{self.robot.kind}'s (robot.kind): expected one of "
                                 f"{list(kind.trajectory_kinds + COMMON_TRAJECTORY_KINDS)}")
            if isinstance(t.amplitude, tuple) and t.kind == "joint_excitation" and \
                    len(t.amplitude) != len(self.robot.actuators):
                raise FieldError(f"trajectories[{i}].amplitude", f"expected one amplitude per actuator "
                                 f"({len(self.robot.actuators)}), got {len(t.amplitude)}")

    def _check_parameter_names(self, known: tuple[str, ...]) -> None:
        """Parameter names of the identification section: those of the robot's model (``known``)."""
        if self.identification is None:
            return
        for s, step in enumerate(self.identification.steps):
            for i, p in enumerate(() if step.parameters == ("all",) else step.parameters):
                if p not in known and not any(fnmatch.fnmatchcase(n, p) for n in known):
                    close = difflib.get_close_matches(p, known, n=1)
                    hint = f"did you mean {close[0]!r}?" if close else f"expected one of {list(known)}"
                    raise FieldError(f"identification.steps[{s}].parameters[{i}]",
                                     f"unknown parameter {p!r} (no parameter matches it); {hint}")
        for name in self.identification.bounds:
            if name not in known:
                raise FieldError(f"identification.bounds.{name}", f"unknown parameter; expected one of {list(known)}")
        kinds = set(known) | {parameter_kind(n) for n in known} | {drive_term(n) for n in known} - {None}
        for section in ("online", "physical"):
            for name in getattr(self.identification, section).scales:
                if name not in kinds:
                    raise FieldError(f"identification.{section}.scales.{name}",
                                     f"unknown parameter or kind; expected one of {sorted(kinds)}")

    def true_parameters(self) -> np.ndarray | None:
        """The simulated rig's true parameters (n,) in the model's order; None without ``sim``."""
        if self.sim is None:
            return None
        return kind_of(self.robot).truth(self.robot, self.sim)

    @property
    def simulated(self) -> bool:
        """True when the bus is served by the simulated rig and cannot reach hardware."""
        return self.sim is not None and self.bus is not None and self.bus.is_local

    @property
    def sync_mode(self) -> str:
        """The SYNC producer of the runs: ``bus.sync``, by default lockstep on the simulated rig."""
        if self.bus is not None and self.bus.sync is not None:
            return self.bus.sync
        return "lockstep" if self.simulated else "periodic"

    @property
    def current(self) -> str:
        """The motor current the drives stream: ``bus.current`` (the instantaneous one without a bus)."""
        return self.bus.current if self.bus is not None else drivers.axis.INSTANTANEOUS

    def trajectory(self, name: str) -> TrajectoryConfig:
        return next(t for t in self.trajectories if t.name == name)
