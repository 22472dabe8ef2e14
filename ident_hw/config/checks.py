"""The cross-field rules of a config: what no single key's type and range can say.

One function per section class (:data:`CHECKS`, handed to :func:`ident_hw.config.schema.build`),
``check(section, written)`` with ``written`` the keys the file gives; each raises
:class:`~ident_hw.config.schema.FieldError` naming the offending key relative to its section.
The whole file's rules (:func:`check_config`) tie the sections together: the identification's
parameter names are the robot model's, every trajectory named exists, the simulated rig's truth
is the robot's, and so on.
"""

from __future__ import annotations

import difflib
import fnmatch

import drivers.errors
from drivers.units import PRISMATIC, REVOLUTE
from ident_hw.model.delta import BODIES, BODY_PARAMS
from ident_hw.model.interface import RobotModel

from .actuators import ActuatorConfig
from .file import Config
from .identification import IdentificationConfig, OnlineConfig, PhysicalConfig
from .robot import RobotConfig
from .robot_delta import DeltaParametersConfig
from .robots import COMMON_TRAJECTORY_KINDS, RobotKind, check_parameter_set, kind_of, model_of
from .scales import check_scales, drive_term, parameter_kind
from .schema import Check, FieldError, ordered_pair
from .sim import TRUTH_KEYS
from .to_drivers import bus_settings, timing_settings, watchdogs
from .to_identification import filter_settings
from .trajectory import COMMON_KEYS, KEYS_OF_KIND, STANDSTILL_MIN_S, STANDSTILL_SETTLE, TrajectoryConfig


# ----------------------------------------------------------------------------- sections
def check_delta_parameters(p: DeltaParametersConfig, written: frozenset = frozenset()) -> None:
    bodies = {f"{b}.{q}" for b in BODIES for q in BODY_PARAMS}
    for name in p.factors:
        if name not in bodies:
            raise FieldError(f"factors.{name}", "unknown body parameter; expected <body>.<parameter>, "
                             f"bodies {list(BODIES)}, parameters {list(BODY_PARAMS)}")


def check_actuator(a: ActuatorConfig, written: frozenset = frozenset()) -> None:
    if a.kind == PRISMATIC and a.screw_lead is None:
        raise FieldError("screw_lead", "missing key: a prismatic actuator needs screw_lead (m per motor turn)")
    if a.kind == REVOLUTE and a.screw_lead is not None:
        raise FieldError("screw_lead", "a revolute actuator has no screw_lead")


def check_robot(robot: RobotConfig, written: frozenset = frozenset()) -> None:
    """Only the sections of the robot's kind, its kind's own rules, the actuators it expects and
    every node id once."""
    kind = kind_of(robot)
    for key in ("description", "modes", "stroke", "described"):
        if getattr(robot, key) is not None and key not in kind.sections:
            raise FieldError(key, f"belongs to another robot than robot.kind {robot.kind!r} "
                                  f"(its sections: {', '.join(kind.sections)})")
    kind.validate(robot)
    names, kinds = kind.actuators(robot)
    if len(robot.actuators) != len(names):
        raise FieldError("actuators", f"expected {len(names)} actuators ({', '.join(names)}), got {len(robot.actuators)}")
    for i, (act, expected) in enumerate(zip(robot.actuators, kinds)):
        if act.kind != expected:
            raise FieldError(f"actuators[{i}].kind",
                             f"actuator {i} ({names[i]}) must be {expected!r}, got {act.kind!r}")
    seen: dict[int, int] = {}
    for i, act in enumerate(robot.actuators):
        if act.node_id is None:
            continue
        if act.node_id in seen:
            raise FieldError(f"actuators[{i}].node_id",
                             f"node id {act.node_id} is already used by actuators[{seen[act.node_id]}]")
        seen[act.node_id] = i


def check_trajectory(t: TrajectoryConfig, written: frozenset = frozenset()) -> None:
    """The keys its kind needs, and no key its kind does not read (it would be silently ignored)."""
    unread = sorted(written - set(COMMON_KEYS) - set(KEYS_OF_KIND[t.kind]))
    if unread:
        reads = ", ".join(KEYS_OF_KIND[t.kind]) or "none"
        raise FieldError(unread[0], f"a {t.kind!r} trajectory does not use {unread[0]} (it would be ignored); "
                                    f"its own keys: {reads}; any trajectory's: {', '.join(COMMON_KEYS)}")
    if (t.kind.startswith("delta_") or t.kind == "joint_excitation") and t.duration is None:
        raise FieldError("duration", f"missing key: a {t.kind!r} trajectory needs duration (s)")
    if t.kind in ("file", "recorded") and t.path is None:
        raise FieldError("path", f"missing key: a {t.kind!r} trajectory needs path")
    if t.rows is not None and t.window is not None:
        raise FieldError("window", "give either rows or window, not both")
    for key in ("rows", "window"):
        pair = getattr(t, key)
        if pair is not None and not pair[0] < pair[1]:
            raise FieldError(key, f"expected [first, last] with first < last, got {list(pair)}")
    if isinstance(t.amplitude, tuple) and t.kind.startswith("delta_") and len(t.amplitude) != 3:
        raise FieldError("amplitude", f"one amplitude per arm is for the Delta's three arms, got "
                                      f"{len(t.amplitude)} for a {t.kind!r} trajectory")
    if t.kind in ("carriage_sweep", "square") and t.size is None:
        raise FieldError("size", f"missing key: a {t.kind!r} trajectory needs size (m)")
    if t.kind == "standstill" and t.duration is not None and t.duration < STANDSTILL_MIN_S:
        raise FieldError("duration", f"a standstill of {t.duration:g} s gives no noise floor: its first "
                                     f"{STANDSTILL_SETTLE:g} s are left out (the drives taking the load) and the "
                                     f"filter trims its ends; at least {STANDSTILL_MIN_S:g} s")


def check_scales_of(section: OnlineConfig | PhysicalConfig, written: frozenset = frozenset()) -> None:
    check_scales(section.scales)


def check_identification(ident: IdentificationConfig, written: frozenset = frozenset()) -> None:
    """At least one step, each with trajectories and parameters, at most one of them least squares;
    every bound ``[min, max]`` with ``min < max``. (An empty list passed ``check`` once, and ``run`` failed
    after recording the whole campaign.)"""
    if not ident.steps:
        raise FieldError("steps", "at least one step is needed: the identification has nothing to fit")
    for i, step in enumerate(ident.steps):
        for key, what in (("trajectories", "trajectory"), ("parameters", "parameter (or [all])")):
            if not getattr(step, key):
                raise FieldError(f"steps[{i}].{key}", f"step {step.name!r} needs at least one {what}")
    least_squares = [i for i, s in enumerate(ident.steps) if s.method in ("wls", "ols")]
    if len(least_squares) > 1:
        raise FieldError(f"steps[{least_squares[1]}].method",
                         f"only one step may fit base parameters by least squares (steps "
                         f"{[ident.steps[i].name for i in least_squares]} are 'wls'/'ols')")
    for i, step in enumerate(ident.steps):
        if (step.method == "gains") != (step.payload is not None):
            raise FieldError(f"steps[{i}].payload", "a 'gains' step needs the payload (its mass and the trajectories "
                             "that carry it); only a 'gains' step has one" if step.method == "gains" else
                             "only a 'gains' step has a payload")
        if step.payload is not None:
            for j, name in enumerate(step.payload.trajectories):
                if name not in step.trajectories:
                    raise FieldError(f"steps[{i}].payload.trajectories[{j}]", f"{name!r} is not one of the step's "
                                     f"trajectories {list(step.trajectories)}")
            if not step.payload.trajectories or set(step.payload.trajectories) == set(step.trajectories):
                raise FieldError(f"steps[{i}].payload.trajectories", "the drive gains need runs with the payload "
                                 "and runs without it")
    for name, pair in ident.bounds.items():
        try:
            ordered_pair(pair)
        except ValueError as exc:    # an equal pair made SciPy's bounded fit fail after the campaign
            raise FieldError(f"bounds.{name}", f"{exc} (to hold {name} at a value, leave it out of the steps)") from exc


# ----------------------------------------------------------------------------- the whole file
def check_config(config: Config, written: frozenset = frozenset()) -> None:
    """The rules that tie the sections together (the module docstring)."""
    model = model_of(config.robot)            # once: a described robot's is read from its file
    _check_parameter_names(config.identification, model.parameter_names)
    kind = kind_of(config.robot)
    _check_sim(config, model, kind)
    names = _check_trajectory_names(config)
    bus = config.bus
    _check_drives(config)
    if bus is not None and bus.heartbeat_timeout is not None:
        raise FieldError("bus.heartbeat_timeout", "retired: the two sides have a timeout each now, "
                         "bus.watchdogs.drive_heartbeat (the master's watch of the drives) and "
                         "bus.watchdogs.master_heartbeat (the drives' watch of the master, 0x1016:01)")
    if bus is not None:
        _check_watchdogs(bus)
    if bus is not None and bus.sync == "lockstep" and not config.simulated:
        raise FieldError("bus.sync", f"lockstep paces the SYNC by the simulated rig's answers; "
                         f"{bus.interface}:{bus.channel} may carry real drives, which "
                         f"need 'periodic'" + ("" if config.sim is not None else " (no sim: section)"))
    _check_fault(config, names)
    _check_friction(config)
    _check_recorded(config)
    _check_filter(config)
    _check_trajectory_kinds(config, kind)
    _check_compare_models(config.identification, model)
    _check_described_only(config.identification, model, config.robot.kind)
    for i, t in enumerate(config.trajectories):
        if t.payload is not None and (config.sim is None or not config.sim.in_process):
            raise FieldError(f"trajectories[{i}].payload", "a payload is put on by the in-process simulated "
                             "rig (sim.in_process: true)")


def _check_friction(config: Config) -> None:
    """A friction model other than Coulomb and viscous is a described robot's, and not simulated
    (the simulated rig's plant has those two only)."""
    friction = config.robot.friction
    if friction.default:
        return
    key = "robot.friction." + ("model" if friction.model != "coulomb" else "offset")
    if not kind_of(config.robot).friction_models:
        raise FieldError(key, f"the {config.robot.kind}'s model has Coulomb and viscous friction only; other friction "
                              "models are for robots read from their description file (robot.kind: described)")
    if config.sim is not None:
        raise FieldError(key, "the simulated rig's plant has Coulomb and viscous friction only: a simulated robot "
                              "is identified with robot.friction.model coulomb and no offset")


def _check_recorded(config: Config) -> None:
    """Recorded trajectories need the ``recordings`` section, one column per actuator in it."""
    recorded = [i for i, t in enumerate(config.trajectories) if t.recorded]
    if not recorded:
        return
    recordings = config.recordings
    if recordings is None:
        raise FieldError(f"trajectories[{recorded[0]}].kind", "a 'recorded' trajectory is read as the recordings "
                                                              "section says (its columns and units): missing section")
    n = len(config.robot.actuators)
    columns = recordings.columns
    if (columns.current is None) == (columns.torque is None):
        raise FieldError("recordings.columns", "give the columns of either current or torque (one per actuator)")
    for key in ("position", "velocity", "current", "torque"):
        given = getattr(columns, key)
        if given is not None and len(given) != n:
            raise FieldError(f"recordings.columns.{key}", f"expected one column per actuator ({n}: "
                             f"{', '.join(a.name for a in config.robot.actuators)}), got {len(given)}")
    if isinstance(recordings.current_delay, tuple) and len(recordings.current_delay) != n:
        raise FieldError("recordings.current_delay", f"expected one delay, or one per actuator ({n}), "
                                                     f"got {len(recordings.current_delay)}")
    for key in ("position", "velocity", "current", "torque"):
        factor = getattr(recordings.scale, key)
        if isinstance(factor, tuple) and len(factor) != n:
            raise FieldError(f"recordings.scale.{key}", f"expected one factor, or one per actuator ({n}), "
                                                        f"got {len(factor)}")


def _check_drives(config: Config) -> None:
    """On a bus, every actuator names its drive: node-ID and profile (a config without a bus,
    which only identifies recordings made elsewhere, may leave them out)."""
    if config.bus is None:
        return
    for i, act in enumerate(config.robot.actuators):
        for key in ("node_id", "profile"):
            if getattr(act, key) is None:
                raise FieldError(f"robot.actuators[{i}].{key}", f"missing key: actuator {act.name!r} is driven on "
                                 f"bus {config.bus.interface}:{config.bus.channel}, which needs its drive's {key}")


def _check_watchdogs(bus) -> None:
    """The heartbeat timeouts longer than the heartbeat period and within what ``0x1016:01`` holds;
    a timing process on a bus another process can reach."""
    try:
        watchdogs(bus)
    except drivers.errors.ConfigError as exc:
        key = "master_heartbeat" if "master_heartbeat" in str(exc) else "drive_heartbeat"
        raise FieldError(f"bus.watchdogs.{key}", str(exc)) from None
    try:
        timing_settings(bus).uses_process(bus_settings(bus))
    except drivers.errors.ConfigError as exc:
        raise FieldError("bus.timing", str(exc)) from None


def _check_filter(config: Config) -> None:
    """The cut-off the identification's filter is given, held to the filter's own rule
    (:class:`ident_hw.filtering.FilterSettings`: below its Nyquist frequency) at the SYNC rate the
    campaign is recorded at. The defaults always pass (at most a quarter of the rate)."""
    ident, bus = config.identification, config.bus
    if ident is None or bus is None or ident.filter.cutoff is None:
        return
    try:
        filter_settings(ident.filter, bus.sync_rate)
    except ValueError as exc:
        raise FieldError("identification.filter.cutoff",
                         f"{ident.filter.cutoff:g} Hz: must lie below half the SYNC rate ({0.5 * bus.sync_rate:g} Hz "
                         f"of bus.sync_rate {bus.sync_rate:g} Hz), the rate the campaign is recorded at ({exc})") from None


def _check_compare_models(ident: IdentificationConfig | None, model: RobotModel) -> None:
    """The model comparison needs a least-squares step and a robot with an energy regressor."""
    if ident is None or not ident.compare_models:
        return
    if not any(s.method in ("wls", "ols") for s in ident.steps):
        raise FieldError("identification.compare_models", "needs a step that fits base parameters by "
                         "least squares (method 'wls' or 'ols')")
    from ident_hw.identification.model_comparison import supports_energy_models
    why = supports_energy_models(model)
    if why:
        raise FieldError("identification.compare_models", why)


def _check_described_only(ident: IdentificationConfig | None, model: RobotModel, kind: str) -> None:
    """A ``gains`` step fits the payload's columns of the regressor
    (:meth:`~ident_hw.model.described.DescribedRobot.payload_indices`) and ``compare_with`` predicts
    with its set's own friction model
    (:meth:`~ident_hw.model.described.DescribedRobot.with_friction`): a described robot's model
    has both, the 3PRRR's and the Delta's own neither."""
    if ident is None:
        return
    keys = [f"identification.steps[{i}].method" for i, s in enumerate(ident.steps) if s.method == "gains"]
    if ident.compare_with is not None:
        keys.append("identification.compare_with")
    if not keys:
        return
    from ident_hw.model.described import DescribedRobot    # pinocchio: described robots only
    if not isinstance(model, DescribedRobot):
        what = "a 'gains' step" if keys[0].endswith("method") else "compare_with"
        raise FieldError(keys[0], f"{what} needs a described robot (robot.kind: described, whose model has the "
                         f"payload's columns and takes any friction model); robot.kind is {kind!r}")


def _check_sim(config: Config, model: RobotModel, kind: RobotKind) -> None:
    """The sim section's truth is the robot kind's (``sim.<truth key>``), and its parameters the model's."""
    sim = config.sim
    if sim is None:
        return
    key = kind.truth_key
    if getattr(sim, key) is None:
        raise FieldError(f"sim.{key}", f"missing key: the simulated {config.robot.kind}'s true parameters")
    for other in TRUTH_KEYS:
        if other != key and getattr(sim, other) is not None:
            raise FieldError(f"sim.{other}", f"belongs to another robot than robot.kind {config.robot.kind!r} "
                             f"(its true parameters are sim.{key})")
    if sim.parameters is not None:
        from ident_hw.model.described import DescribedRobot    # pinocchio: described robots only
        if not isinstance(model, DescribedRobot):   # sim.parameters is only the described kind's truth key (above)
            raise FieldError("sim.parameters", f"belongs to a described robot, not robot.kind {config.robot.kind!r}")
        try:
            check_parameter_set(sim.parameters, model)
        except FieldError as exc:
            raise FieldError(f"sim.parameters.{exc.key}", exc.message) from None


def _check_trajectory_names(config: Config) -> dict[str, int]:
    """Every trajectory name once, and every one the identification names defined; returns
    name -> index."""
    names: dict[str, int] = {}
    for i, t in enumerate(config.trajectories):
        if t.name in names:
            raise FieldError(f"trajectories[{i}].name", f"trajectory name {t.name!r} is used twice")
        names[t.name] = i
    ident = config.identification
    if ident is None:
        return names
    for s, step in enumerate(ident.steps):
        for j, name in enumerate(step.trajectories):
            if name not in names:
                raise FieldError(f"identification.steps[{s}].trajectories[{j}]",
                                 f"no trajectory named {name!r}; defined: {list(names)}")
    for j, name in enumerate(ident.validation):
        if name not in names:
            raise FieldError(f"identification.validation[{j}]",
                             f"no trajectory named {name!r}; defined: {list(names)}")
    return names


def _check_fault(config: Config, names: dict[str, int]) -> None:
    """An injected fault names a trajectory and an actuator of this config, on the in-process rig."""
    sim = config.sim
    fault = sim.fault if sim is not None else None
    if sim is None or fault is None:
        return
    if fault.trajectory not in names:
        raise FieldError("sim.fault.trajectory", f"no trajectory named {fault.trajectory!r}; "
                         f"defined: {list(names)}")
    if fault.node_id not in [a.node_id for a in config.robot.actuators]:
        raise FieldError("sim.fault.node_id", f"no actuator with node id {fault.node_id}")
    if not sim.in_process:
        raise FieldError("sim.fault", "fault injection needs the in-process rig (sim.in_process: true)")


def _check_trajectory_kinds(config: Config, kind: RobotKind) -> None:
    """Every trajectory of a kind the robot has, a joint excitation's amplitudes one per actuator."""
    allowed = kind.trajectory_kinds + COMMON_TRAJECTORY_KINDS
    actuators = len(config.robot.actuators)
    for i, t in enumerate(config.trajectories):
        if t.kind not in allowed:
            raise FieldError(f"trajectories[{i}].kind", f"a {t.kind!r} trajectory is not one of the "
                             f"{config.robot.kind}'s (robot.kind): expected one of {list(allowed)}")
        if isinstance(t.amplitude, tuple) and t.kind == "joint_excitation" and len(t.amplitude) != actuators:
            raise FieldError(f"trajectories[{i}].amplitude", f"expected one amplitude per actuator "
                             f"({actuators}), got {len(t.amplitude)}")


def _check_parameter_names(ident: IdentificationConfig | None, known: tuple[str, ...]) -> None:
    """Parameter names of the identification section: those of the robot's model (``known``)."""
    if ident is None:
        return
    for s, step in enumerate(ident.steps):
        for i, p in enumerate(() if step.parameters == ("all",) else step.parameters):
            if p not in known and not any(fnmatch.fnmatchcase(n, p) for n in known):
                close = difflib.get_close_matches(p, known, n=1)
                hint = f"did you mean {close[0]!r}?" if close else f"expected one of {list(known)}"
                raise FieldError(f"identification.steps[{s}].parameters[{i}]",
                                 f"unknown parameter {p!r} (no parameter matches it); {hint}")
    for name in ident.bounds:
        if name not in known:
            raise FieldError(f"identification.bounds.{name}", f"unknown parameter; expected one of {list(known)}")
    kinds = set(known) | {parameter_kind(n) for n in known} | {t for n in known if (t := drive_term(n)) is not None}
    for section in ("online", "physical"):
        for name in getattr(ident, section).scales:
            if name not in kinds:
                raise FieldError(f"identification.{section}.scales.{name}",
                                 f"unknown parameter or kind; expected one of {sorted(kinds)}")


#: every section's cross-field check, by section class
CHECKS: dict[type, Check] = {
    DeltaParametersConfig: check_delta_parameters,
    ActuatorConfig: check_actuator,
    RobotConfig: check_robot,
    TrajectoryConfig: check_trajectory,
    OnlineConfig: check_scales_of,
    PhysicalConfig: check_scales_of,
    IdentificationConfig: check_identification,
    Config: check_config,
}
