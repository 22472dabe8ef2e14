"""The campaign's trajectories from a config, and the checks run before any bus is opened."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import trajectories
from drivers.axis import AxisConfig, outside_position_limits
from drivers.firmware import load_object_dictionary
from ident_hw.config import Config, TrajectoryConfig
from ident_hw.config.robots import kind_of, model_of
from ident_hw.config.to_drivers import axis_config, axis_scaling
from ident_hw.config.to_trajectories import excitation_of
from ident_hw.config.trajectory import REST_TO_REST_KINDS, STANDSTILL_S
from ident_hw.filtering import POSITION_MARGIN
from ident_hw.model import KinematicsError
from ident_hw.model.interface import POSITION_UNITS, RobotModel


@dataclass
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
        if self.error:
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


def robot_model(config: Config) -> RobotModel:
    """The model of the config's robot (``robot.kind``)."""
    return model_of(config.robot)


def sample_rate(config: Config) -> float:
    """Trajectory sample rate = the SYNC rate of the bus (250 Hz without a bus section)."""
    return config.bus.sync_rate if config.bus is not None else 250.0


def sync_period(config: Config) -> float:
    """The period (s) at which ``run`` streams the set-points: one SYNC, one sample of :func:`build`."""
    return 1.0 / sample_rate(config)


def setpoints(traj: trajectories.Trajectory) -> np.ndarray:
    """The set-points ``run`` streams for ``traj``: ``(n, a)`` rad | m in actuator order, one row
    per SYNC period (:func:`sync_period`), the first where the drives are moved to before it.
    The runner hands exactly this array to ``run_cyclic``; :func:`check` validates exactly it."""
    return traj.Theta


def drive_axes(config: Config) -> list[AxisConfig]:
    """The drives' axis settings of the config's actuators, their software position limits
    included: those of the run's drive group (:meth:`ident_hw.experiment.session.Session.drive_group`)."""
    return [axis_config(a, config.base_dir, config.current) for a in config.robot.actuators]


def build(config: Config, tcfg: TrajectoryConfig, robot: RobotModel) -> trajectories.Trajectory:
    """Generate one trajectory (all cycles) at the SYNC rate."""
    rate = sample_rate(config)
    if tcfg.kind == "file":
        traj = trajectories.load(tcfg.path).resample(rate)     # relative to the config when it was read
    elif tcfg.kind == "standstill":
        traj = trajectories.standstill(robot, tcfg.duration or STANDSTILL_S, rate, tcfg.name)
    else:
        traj = kind_of(config.robot).build(config, tcfg, robot, rate)
    traj = repeat(traj, tcfg.cycles)
    traj.name = tcfg.name
    return traj


def motion_bandwidth(config: Config, name: str) -> float:
    """Bandwidth (Hz) of the motion of trajectory ``name``, for its identification filter: its
    ``bandwidth`` key, else the highest harmonic of a Fourier excitation, else the identification
    filter's ``bandwidth`` (also for a name the config does not list)."""
    tcfg = next((t for t in config.trajectories if t.name == name), None)
    if tcfg is not None and tcfg.bandwidth is not None:
        return tcfg.bandwidth
    if tcfg is not None and tcfg.kind == "fourier":
        return excitation_of(config, tcfg).bandwidth
    return config.identification.filter.bandwidth


def position_margin(config: Config, name: str) -> float:
    """How far above the identification's band the positions of trajectory ``name`` are
    low-passed (:attr:`ident_hw.filtering.FilterSettings.position_margin`): the config's
    ``identification.filter.position_margin`` where it gives one, else
    :data:`ident_hw.filtering.POSITION_MARGIN` for the rest-to-rest kinds
    (:data:`ident_hw.config.trajectory.REST_TO_REST_KINDS`), whose force near the band edge would
    otherwise be biased, and 1 (one cut-off) for band-limited motions and for a name the config
    does not list."""
    if config.identification.filter.position_margin is not None:
        return config.identification.filter.position_margin
    tcfg = next((t for t in config.trajectories if t.name == name), None)
    return POSITION_MARGIN if tcfg is not None and tcfg.kind in REST_TO_REST_KINDS else 1.0


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
    robot = robot_model(config)
    out = []
    streamed = [t for t in config.trajectories if not t.recorded]
    ordered = [t for t in streamed if not t.online_only] + [t for t in streamed if t.online_only]
    for tcfg in ordered:
        if names is not None and tcfg.name not in names:
            continue
        if names is None and tcfg.online_only and not online:
            continue
        try:
            traj = build(config, tcfg, robot)
            report = check(config, traj, robot)
        except (ValueError, KinematicsError, trajectories.TrajectoryFileError, OSError) as exc:
            out.append(PlannedTrajectory(tcfg, None, None, error=str(exc)))
            continue
        if late := events_past_the_end(config, tcfg, traj.duration):
            out.append(PlannedTrajectory(tcfg, None, None, error=late))
            continue
        out.append(PlannedTrajectory(tcfg, traj, report, notes=quantisation_notes(config, traj)))
    return out


def events_past_the_end(config: Config, tcfg: TrajectoryConfig, duration: float) -> str:
    """What the config sets to happen during trajectory ``tcfg`` (its ``payload``, the simulated
    rig's ``sim.fault``) at or after its end (``duration`` s): it would never happen, and the run
    would look like one where it did. Empty if nothing."""
    events = []
    if tcfg.payload is not None:
        events.append(("payload.after", tcfg.payload.after))
    fault = config.sim.fault if config.sim is not None else None
    if fault is not None and fault.trajectory == tcfg.name:
        events.append(("sim.fault.after", fault.after))
    return "; ".join(f"{key} {after:g} s is at or past its end ({duration:.3g} s): it would never happen"
                     for key, after in events if after >= duration)


def check(config: Config, traj: trajectories.Trajectory, robot: RobotModel) -> trajectories.Report:
    """The feasibility report of ``traj`` on the config's robot: its kind's check (reach, safety
    margins, speeds and accelerations) and the set-points ``run`` streams checked as
    ``run_cyclic`` checks them (:func:`setpoint_violations`): a trajectory this accepts streams
    without a limit stop. The set-point check stands for the kind's ``position`` check (the
    actuators' limits, the same numbers, drawn here where ``run_cyclic`` draws them); the 3PRRR's
    ``stroke`` check of the guides stays."""
    acts = config.robot.actuators
    if traj.Theta.shape[1] != len(acts):
        raise ValueError(f"trajectory {traj.name!r} moves {traj.Theta.shape[1]} actuators, the robot has {len(acts)}")
    report = kind_of(config.robot).check(config, traj, robot)
    found = [v for v in report.violations if v.quantity != "position"] + setpoint_violations(config, traj)
    report.violations = sorted(found, key=lambda v: v.sample)
    return report


def setpoint_violations(config: Config, traj: trajectories.Trajectory) -> list[trajectories.Violation]:
    """Per drive, the first of the set-points ``run`` streams for ``traj`` (:func:`setpoints`)
    outside its software position limits, by the very test ``run_cyclic`` applies before it
    streams (:func:`drivers.axis.outside_position_limits`, on the axes of :func:`drive_axes`)."""
    axes, targets = drive_axes(config), setpoints(traj)
    outside = outside_position_limits(axes, targets)
    found = []
    for j in np.flatnonzero(outside.any(axis=0)):
        k = int(np.argmax(outside[:, j]))
        axis, value = axes[j], float(targets[k, j])
        limit = axis.position_max if value > axis.position_max else axis.position_min
        found.append(trajectories.Violation(float(traj.t[k]), k, None, "set-point", axis.name, value, limit,
                                            POSITION_UNITS[axis.scaling.kind]))
    return found


def quantisation_notes(config: Config, traj: trajectories.Trajectory) -> tuple[str, ...]:
    """Advice (not an error): the axes on which one encoder count per SYNC period, as a demand
    acceleration (``1 / (counts_per_unit T²)``), exceeds the trajectory's RMS acceleration. The
    set-points are whole counts, so the drives' interpolated demand ripples by that much: the
    currents carry it (the identification filters it out, at the cost of noise). Only where the
    user should act on it: with ``identification.encoder_draws`` (the default), every sigma and
    the verdict's noise floor hold the encoders' resolution, and nothing is said; without, the
    sigma would leave it out."""
    if config.identification is not None and config.identification.encoder_draws:
        return ()
    period = 1.0 / sample_rate(config)
    parts = []
    for j, axis in enumerate(config.robot.actuators):
        rms = float(np.sqrt(np.mean(traj.Thetadd[:, j] ** 2)))
        quantum = 1.0 / (axis_scaling(axis).counts_per_unit * period**2)
        if 0 < rms < quantum:
            unit = "rad/s²" if axis.kind == "revolute" else "m/s²"
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


def homing_problems(config: Config, robot: RobotModel | None = None) -> list[str]:
    """Homing offsets that would stop a run or mislead the model, as messages: one outside its
    axis's position limits (the drive would stop on its software position limit at home), or,
    for a method homing on the current position (:data:`HOME_ON_CURRENT_POSITION`), one away
    from the coordinate the model gives that axis at the robot's home pose (the drives and the
    model would then disagree by the difference for the whole run) by more than
    :data:`HOME_TOLERANCE_COUNTS` encoder counts. None without a bus (no drive to home) or for an
    actuator without homing."""
    if config.bus is None:
        return []
    robot = robot_model(config) if robot is None else robot
    home = robot.home_actuated()
    problems = []
    for j, (act, axis) in enumerate(zip(config.robot.actuators, drive_axes(config))):
        if act.homing is None:
            continue
        offset, unit = act.homing.offset, POSITION_UNITS[act.kind]
        where = f"{config.source}: robot.actuators[{j}] ({act.name}) homing.offset {offset:.6g} {unit}"
        if outside_position_limits([axis], np.array([[offset]]))[0, 0]:
            problems.append(f"{where} is outside its position limits [{axis.position_min:.6g}, "
                            f"{axis.position_max:.6g}] {unit}: the drive would stop on its software position limit "
                            "as soon as it is homed")
        elif act.homing.method in HOME_ON_CURRENT_POSITION:
            tolerance = HOME_TOLERANCE_COUNTS / axis_scaling(act).counts_per_unit
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
    problems += homing_problems(config)
    for p in plan(config, online=True) if planned is None else planned:
        if not p.ok:
            problems.append(p.describe())
    problems += dictionary_problems(config)
    return problems


def dictionary_problems(config: Config) -> list[str]:
    """Each actuator's own object dictionary file (``object_dictionary``) held to the objects a
    run uses on its drive (:func:`drivers.firmware.load_object_dictionary`): what a file lacks,
    and that ``ident-hw home`` works on it where homing needs nothing it lacks."""
    problems = []
    if config.bus is None:             # no drives to hold to them (recordings made elsewhere)
        return problems
    for axis in drive_axes(config):
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
