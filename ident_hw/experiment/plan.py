"""The campaign's trajectories from a config, and the checks run before any bus is opened."""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import trajectories
from drivers.axis import AxisConfig, outside_position_limits
from drivers.firmware import load_object_dictionary
from ident_hw.config import ActuatorConfig, BusConfig, Config, RobotConfig, SimFaultConfig, TrajectoryConfig
from ident_hw.config.robots import model_of
from ident_hw.config.to_drivers import axis_config
from ident_hw.config.trajectory import STANDSTILL_S
from ident_hw.model import KinematicsError
from ident_hw.model.interface import POSITION_UNITS, RobotModel

from .robot_trajectories import trajectories_of


@dataclass(frozen=True)
class PlannedTrajectory:
    """One trajectory of the campaign, sampled at the SYNC rate, with its feasibility report."""

    config: TrajectoryConfig
    trajectory: trajectories.Trajectory | None
    report: trajectories.Report | None
    error: str = ""
    notes: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return self.trajectory is not None and self.report is not None and self.report.ok

    def describe(self) -> str:
        if self.error or self.report is None or self.trajectory is None:
            return f"{self.config.name}: cannot build: {self.error}"
        if not self.report.ok:
            return f"{self.config.name}: INFEASIBLE: {self.report.first}"
        t = self.trajectory
        text = f"{self.config.name}: ok ({t.duration:.1f} s, {len(t.t)} samples"
        optimised = t.metadata.get("optimised")
        if optimised:
            text += (f"; optimised excitation: scaled condition of the base regressor {optimised['cond_initial']:.3g} "
                     f"drawn, {optimised['cond_final']:.3g} optimised")
        return "\n    note: ".join([text + ")", *self.notes])


@dataclass(frozen=True)
class PlanInputs:
    """What planning a campaign takes of the config, made once (:meth:`of`): the config file
    (``source``, for messages), its robot section and model, the SYNC rate (Hz; 250 without a
    bus), the folder a drive's object dictionary file is relative to, the motor current the drives stream, the
    identification filter's band (Hz, what a described robot's excitation is band-limited to
    without a ``bandwidth`` of its own), the encoder draws the identification takes, the
    simulated rig's fault, and whether there is a bus (homing matters only then). Each drive's
    axis settings (:attr:`axes`) are made where a check needs them: a config of recordings made
    elsewhere has no drives to name."""

    source: str
    robot: RobotConfig
    model: RobotModel
    rate: float
    base_dir: Path | None
    current: str
    bandwidth: float
    encoder_draws: int
    fault: SimFaultConfig | None
    has_bus: bool

    @classmethod
    def of(cls, config: Config) -> PlanInputs:
        """The inputs of a config (its robot's model built)."""
        ident = config.identification
        return cls(source=config.source, robot=config.robot, model=model_of(config.robot),
                   rate=sample_rate(config.bus), base_dir=config.base_dir,
                   current=config.current,
                   bandwidth=ident.filter.bandwidth if ident is not None else 2.0,
                   encoder_draws=ident.encoder_draws if ident is not None else 0,
                   fault=config.sim.fault if config.sim is not None else None, has_bus=config.bus is not None)

    @functools.cached_property
    def axes(self) -> tuple[AxisConfig, ...]:
        """Each drive's axis settings (:func:`drive_axes`).

        Raises:
            ConfigError: an actuator without the drive data a run needs (its node-ID...).
        """
        return tuple(drive_axes(self.robot.actuators, self.base_dir, self.current))

    @property
    def columns(self) -> tuple[tuple[str, str], ...]:
        """The robot's actuators as a trajectory file names its columns: (name, unit of position)."""
        return tuple((a.name, POSITION_UNITS[a.kind]) for a in self.robot.actuators)


def sample_rate(bus: BusConfig | None) -> float:
    """Trajectory sample rate = the SYNC rate of the bus (250 Hz without a bus section)."""
    return bus.sync_rate if bus is not None else 250.0


def sync_period(bus: BusConfig | None) -> float:
    """The period (s) at which ``run`` streams the set-points: one SYNC, one sample of :func:`build`."""
    return 1.0 / sample_rate(bus)


def setpoints(traj: trajectories.Trajectory) -> np.ndarray:
    """The set-points ``run`` streams for ``traj``: ``(n, a)`` rad | m in actuator order, one row
    per SYNC period (:func:`sync_period`), the first where the drives are moved to before it.
    The runner hands exactly this array to ``run_cyclic``; :func:`check` validates exactly it."""
    return traj.Theta


def drive_axes(actuators: Sequence[ActuatorConfig], base_dir: Path | None, current: str) -> list[AxisConfig]:
    """The drives' axis settings of the config's ``actuators`` (``base_dir``: the config's folder;
    ``current``: the motor current they stream, ``bus.current``), their software position limits
    included: those of the run's drive group (:meth:`ident_hw.experiment.session.Session.drive_group`)."""
    return [axis_config(a, base_dir, current) for a in actuators]


def build(inputs: PlanInputs, tcfg: TrajectoryConfig) -> trajectories.Trajectory:
    """Generate one trajectory (all cycles) at the SYNC rate: a file's (its columns the robot's
    actuators, :mod:`trajectories.files`), a standstill, or one of the robot kind's
    (:mod:`ident_hw.experiment.robot_trajectories`)."""
    rate = inputs.rate
    if tcfg.kind == "file":
        traj = _from_file(Path(str(tcfg.path)), inputs.columns).resample(rate)   # relative to the config when read
    elif tcfg.kind == "standstill":
        traj = trajectories.standstill(inputs.model, tcfg.duration or STANDSTILL_S, rate, tcfg.name)
    else:
        traj = trajectories_of(inputs.robot).build(inputs.robot, tcfg, inputs.model, rate, inputs.bandwidth)
    return dataclasses.replace(repeat(traj, tcfg.cycles), name=tcfg.name)


def _from_file(path: Path, columns: tuple[tuple[str, str], ...]) -> trajectories.Trajectory:
    """The trajectory of a file whose columns are the robot's actuators (``columns``: name, unit)."""
    found = trajectories.read(path)
    if found.actuators != columns:
        raise trajectories.TrajectoryFileError(
            f"{path}: its columns are the actuators {', '.join(f'{n}[{u}]' for n, u in found.actuators)}; the robot's "
            f"are {', '.join(f'{n}[{u}]' for n, u in columns)} (trajectories.save(traj, path, actuators) writes them)")
    return found.trajectory


def repeat(traj: trajectories.Trajectory, cycles: int) -> trajectories.Trajectory:
    """The trajectory ``cycles`` times back to back (it must end where it starts, at rest)."""
    if cycles == 1:
        return traj
    ends = np.concatenate([traj.Theta[-1] - traj.Theta[0], traj.Thetad[[0, -1]].ravel()])
    if np.max(np.abs(ends)) > 1e-9:
        raise ValueError(f"trajectory {traj.name!r} does not end where it starts at rest: cannot repeat it")
    period = traj.duration + float(traj.t[1] - traj.t[0])
    t = np.concatenate([traj.t + i * period for i in range(cycles)])
    arrays = {k: np.tile(getattr(traj, k), (cycles, 1)) for k in ("X", "Xd", "Xdd", "Theta", "Thetad", "Thetadd")}
    return trajectories.Trajectory(traj.name, t, metadata={**traj.metadata, "cycles": cycles}, **arrays)


def plan(config: Config, names: list[str] | None = None, online: bool = False) -> list[PlannedTrajectory]:
    """Build and check the config's trajectories (``names``: a subset, in campaign order), the
    ``online_only`` ones where ``online`` (``ident-hw online``, ``check``) or named, after the others.
    ``recorded`` trajectories are recordings made elsewhere, not streamed: they are not planned
    (:func:`check_campaign` refuses to run a config that has them)."""
    inputs = PlanInputs.of(config)
    out = []
    streamed = [t for t in config.trajectories if not t.recorded]
    ordered = [t for t in streamed if not t.online_only] + [t for t in streamed if t.online_only]
    for tcfg in ordered:
        if names is not None and tcfg.name not in names:
            continue
        if names is None and tcfg.online_only and not online:
            continue
        try:
            traj = build(inputs, tcfg)
            report = check(inputs, traj)
        except (ValueError, KinematicsError, trajectories.TrajectoryFileError, OSError) as exc:
            out.append(PlannedTrajectory(tcfg, None, None, error=str(exc)))
            continue
        if late := events_past_the_end(tcfg, inputs.fault, traj.duration):
            out.append(PlannedTrajectory(tcfg, None, None, error=late))
            continue
        out.append(PlannedTrajectory(tcfg, traj, report, notes=quantisation_notes(inputs, traj)))
    return out


def cycles_planned(planned: Sequence[PlannedTrajectory]) -> dict[str, int]:
    """Samples (SYNC cycles) of each trajectory of ``planned`` that could be built, by name."""
    return {p.config.name: len(p.trajectory.t) for p in planned if p.trajectory is not None}


def events_past_the_end(tcfg: TrajectoryConfig, fault: SimFaultConfig | None, duration: float) -> str:
    """What the config sets to happen during trajectory ``tcfg`` (its ``payload``, the simulated
    rig's ``fault``) at or after its end (``duration`` s): it would never happen, and the run
    would look like one where it did. Empty if nothing."""
    events = []
    if tcfg.payload is not None:
        events.append(("payload.after", tcfg.payload.after))
    if fault is not None and fault.trajectory == tcfg.name:
        events.append(("sim.fault.after", fault.after))
    return "; ".join(f"{key} {after:g} s is at or past its end ({duration:.3g} s): it would never happen"
                     for key, after in events if after >= duration)


def check(inputs: PlanInputs, traj: trajectories.Trajectory) -> trajectories.Report:
    """The feasibility report of ``traj`` on the config's robot: its kind's check (reach, safety
    margins, speeds and accelerations) and the set-points ``run`` streams checked as
    ``run_cyclic`` checks them (:func:`setpoint_violations`): a trajectory this accepts streams
    without a limit stop. The set-point check stands for the kind's ``position`` check (the
    actuators' limits, the same numbers, drawn here where ``run_cyclic`` draws them); the 3PRRR's
    ``stroke`` check of the guides stays."""
    acts = inputs.robot.actuators
    if traj.Theta.shape[1] != len(acts):
        raise ValueError(f"trajectory {traj.name!r} moves {traj.Theta.shape[1]} actuators, the robot has {len(acts)}")
    report = trajectories_of(inputs.robot).check(inputs.robot, traj, inputs.model)
    found = [v for v in report.violations if v.quantity != "position"] + setpoint_violations(inputs.axes, traj)
    return dataclasses.replace(report, violations=tuple(sorted(found, key=lambda v: v.sample)))


def setpoint_violations(axes: Sequence[AxisConfig], traj: trajectories.Trajectory) -> list[trajectories.Violation]:
    """Per drive, the first of the set-points ``run`` streams for ``traj`` (:func:`setpoints`)
    outside its software position limits, by the very test ``run_cyclic`` applies before it
    streams (:func:`drivers.axis.outside_position_limits`, on the drives' ``axes``, :func:`drive_axes`)."""
    targets = setpoints(traj)
    outside = outside_position_limits(axes, targets)
    found = []
    for j in map(int, np.flatnonzero(outside.any(axis=0))):
        k = int(np.argmax(outside[:, j]))
        axis, value = axes[j], float(targets[k, j])
        limit = axis.position_max if value > axis.position_max else axis.position_min
        found.append(trajectories.Violation(float(traj.t[k]), k, None, "set-point", axis.name, value, limit,
                                            POSITION_UNITS[axis.scaling.kind]))
    return found


def quantisation_notes(inputs: PlanInputs, traj: trajectories.Trajectory) -> tuple[str, ...]:
    """Advice (not an error): the axes on which one encoder count per SYNC period, as a demand
    acceleration (``1 / (counts_per_unit T²)``), exceeds the trajectory's RMS acceleration. The
    set-points are whole counts, so the drives' interpolated demand ripples by that much: the
    currents carry it (the identification filters it out, at the cost of noise). Only where the
    user should act on it: with ``identification.encoder_draws`` (the default), every sigma and
    the verdict's noise floor hold the encoders' resolution, and nothing is said; without, the
    sigma would leave it out."""
    if inputs.encoder_draws:
        return ()
    period = 1.0 / inputs.rate
    parts = []
    for j, axis in enumerate(inputs.axes):
        rms = float(np.sqrt(np.mean(traj.Thetadd[:, j] ** 2)))
        quantum = 1.0 / (axis.scaling.counts_per_unit * period**2)
        if 0 < rms < quantum:
            unit = f"{POSITION_UNITS[axis.scaling.kind]}/s²"
            parts.append(f"{axis.name} {quantum:.3g} {unit} = {quantum / rms:.1f}x its RMS")
    if not parts:
        return ()
    return (f"one encoder count per SYNC period as an acceleration exceeds this motion's: {'; '.join(parts)}. "
            "Expect current ripple at the set-point rate (a finer encoder or a slower SYNC lowers it); with "
            "identification.encoder_draws 0 the sigma leave the encoders' resolution out",)


#: CiA 402 homing methods that take the current position as home (35, and 37 of newer firmware):
#: the robot stands at its home pose when it homes, so the offset is that pose's coordinate
HOME_ON_CURRENT_POSITION = (35, 37)
#: encoder counts a homing offset may stand from the model's home coordinate (a config rounded
#: to a few decimals, not a drive that would disagree with the model)
HOME_TOLERANCE_COUNTS = 10


def homing_problems(inputs: PlanInputs) -> list[str]:
    """Homing offsets that would stop a run or mislead the model, as messages: one outside its
    axis's position limits (the drive would stop on its software position limit at home), or,
    for a method homing on the current position (:data:`HOME_ON_CURRENT_POSITION`), one away
    from the coordinate the model gives that axis at the robot's home pose (the drives and the
    model would then disagree by the difference for the whole run) by more than
    :data:`HOME_TOLERANCE_COUNTS` encoder counts. None without a bus (no drive to home) or for an
    actuator without homing."""
    if not inputs.has_bus:
        return []
    home = inputs.model.home_actuated()
    problems = []
    for j, (act, axis) in enumerate(zip(inputs.robot.actuators, inputs.axes)):
        if act.homing is None:
            continue
        offset, unit = act.homing.offset, POSITION_UNITS[act.kind]
        where = f"{inputs.source}: robot.actuators[{j}] ({act.name}) homing.offset {offset:.6g} {unit}"
        if outside_position_limits([axis], np.array([[offset]]))[0, 0]:
            problems.append(f"{where} is outside its position limits [{axis.position_min:.6g}, "
                            f"{axis.position_max:.6g}] {unit}: the drive would stop on its software position limit "
                            "as soon as it is homed")
        elif act.homing.method in HOME_ON_CURRENT_POSITION:
            tolerance = HOME_TOLERANCE_COUNTS / axis.scaling.counts_per_unit
            if abs(offset - home[j]) > tolerance:
                problems.append(f"{where}: homing method {act.homing.method} takes the current position as home, "
                                f"where the model puts {act.name} at {home[j]:.6g} {unit} ({offset - home[j]:+.4g} "
                                f"{unit} apart, more than {HOME_TOLERANCE_COUNTS} encoder counts): set the offset to "
                                f"{home[j]:.6f}, or the robot's home in its description")
    return problems


def check_campaign(config: Config, planned: list[PlannedTrajectory] | None = None) -> list[str]:
    """Everything that would stop a run, as messages; empty when the campaign can run
    (``planned``: the config's :func:`plan`, if already made)."""
    problems = []
    if config.bus is None:
        problems.append(f"{config.source}: bus: missing section (needed to run)")
    elif config.sim is not None and config.sim.in_process and not config.simulated:
        problems.append(f"{config.source}: sim.in_process: the simulated rig only serves a virtual or vcan bus, "
                        f"not {config.bus.interface}:{config.bus.channel}")
    if not config.trajectories:
        problems.append(f"{config.source}: trajectories: none defined")
    recorded = [t.name for t in config.trajectories if t.recorded]
    if recorded:
        problems.append(f"{config.source}: trajectories {', '.join(recorded)} are recordings made elsewhere: "
                        f"nothing to stream; identify them with `ident-hw identify {config.source}`")
    if config.identification is None:
        problems.append(f"{config.source}: identification: missing section (the steps that turn the "
                        "recordings into parameters; a run would move, record, then stop)")
    inputs = PlanInputs.of(config)
    problems += homing_problems(inputs)
    for p in plan(config, online=True) if planned is None else planned:
        if not p.ok:
            problems.append(p.describe())
    problems += dictionary_problems(inputs)
    return problems


def dictionary_problems(inputs: PlanInputs) -> list[str]:
    """Each actuator's own object dictionary file (``object_dictionary``) held to the objects a
    run uses on its drive (:func:`drivers.firmware.load_object_dictionary`): what a file lacks,
    and that ``ident-hw home`` works on it where homing needs nothing it lacks."""
    problems: list[str] = []
    if not inputs.has_bus:             # no drives to hold to them (recordings made elsewhere)
        return problems
    for axis in inputs.axes:
        if axis.object_dictionary is None:
            continue
        try:
            load_object_dictionary(axis.object_dictionary, axis.profile, axis.node_id, axis.current)
        except ValueError as exc:
            try:
                load_object_dictionary(axis.object_dictionary, axis.profile, axis.node_id, axis.current,
                                       ("bring_up", "home"))
                homing = "; `ident-hw home` works on it"
            except ValueError:
                homing = ""
            problems.append(f"{axis.label}: {exc}: `run` would be refused at bring-up{homing}")
    return problems
