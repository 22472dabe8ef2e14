"""Identification from recorded samples: the config's steps, then validation (no bus involved).

:func:`identify` makes the config's :class:`~ident_hw.experiment.inputs.IdentificationPlan` and
assembles the result from the jobs of its own modules: the friction model's constants chosen on
the data (:mod:`.friction_choice`), each recording prepared (:mod:`.preparation`), the encoders
read again (:mod:`.uncertainty`), the steps in their order (:mod:`.steps`), the base-parameter
analysis of all identification data, the forces of a parameter set from elsewhere
(:mod:`.compared`), the physically consistent parameters, and the quality verdict on what the
per-axis checks need (:mod:`.evidence`, :func:`ident_hw.experiment.quality.verdict`). The result
is a :class:`ident_hw.results.Results`, built once. With ``identification.compare_models``, the
least-squares step's recordings also give the power and energy models' rows, and the three
models' base parameters are fitted side by side (:mod:`ident_hw.identification.model_comparison`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from drivers.errors import RecordingError
from drivers.recording import Recording
from ident_hw.config import Config
from ident_hw.config.identification import IdentificationConfig
from ident_hw.identification.base_params import base_parameters
from ident_hw.identification.least_squares import check_regression_data, stack
from ident_hw.model.interface import RobotModel
from ident_hw.records import BaseAnalysis, BaseStep, ImportSummary, StepRecord, Verdict
from ident_hw.results import ParameterTable, Results, TrajectoryFit

from .compared import compared_set, predicted_forces
from .evidence import axis_evidence
from .friction_choice import friction_robot
from .inputs import IdentificationPlan, identification_plan
from .preparation import Prepared, prepare, prepare_all, rest_speeds
from .quality import verdict
from .plan import cycles_planned, plan as plan_trajectories
from .recordings import require_trajectories
from .steps import consistent, run_steps
from .uncertainty import encoder_draws

logger = logging.getLogger(__name__)


def identify(config: Config, recordings: Mapping[str, Recording],
             imported: Mapping[str, ImportSummary] | None = None) -> Results:
    """Run the config's identification steps and validation on ``recordings`` (name → samples);
    ``imported``: how the recordings made elsewhere were read (:mod:`ident_hw.experiment.external`).
    The entry point: makes the config's plan (:func:`~ident_hw.experiment.inputs.identification_plan`)
    and runs :func:`identify_plan`.

    Raises:
        ValueError: no identification section; RecordingError: a trajectory the steps need has
            no recording, or a recording cannot be prepared.
    """
    if config.identification is None:
        raise ValueError(f"{config.source}: identification: missing section")
    require_trajectories(config.identification, config.source, recordings)
    ident = config.identification
    needed = dict.fromkeys([n for s in ident.steps for n in s.trajectories] + list(ident.validation))
    unsaid = [name for name in needed if not recordings[name].metadata.n_targets]
    cycles = cycles_planned(plan_trajectories(config, unsaid)) if unsaid else {}
    return identify_plan(identification_plan(config, cycles), recordings, imported)


def _base_step_trajectories(ident: IdentificationConfig) -> tuple[str, ...]:
    """The trajectories of the least-squares step, else of every step: what a friction constant
    is chosen on (:mod:`ident_hw.experiment.friction_choice`)."""
    least_squares = [s for s in ident.steps if s.method in ("wls", "ols")]
    steps = least_squares or ident.steps
    return tuple(dict.fromkeys(t for s in steps for t in s.trajectories))


def identify_plan(plan: IdentificationPlan, recordings: Mapping[str, Recording],
                  imported: Mapping[str, ImportSummary] | None = None) -> Results:
    """:func:`identify` of a plan already made: the result, assembled once (module docstring)."""
    ident = plan.identification
    choice = friction_robot(plan.robot, plan.model, recordings, _base_step_trajectories(ident),
                            lambda robot, name, rec: prepare(plan, robot, name, rec))
    robot = choice.robot
    names = robot.parameter_names
    compared: tuple[str, ...] = ()
    if ident.compare_models:            # the config check made sure there is such a step
        compared = next(s for s in ident.steps if s.method in ("wls", "ols")).trajectories
    prepared_set = prepare_all(plan, robot, recordings, compared, imported)
    prepared = prepared_set.prepared
    fitted_names = plan.fitted
    draws = encoder_draws(plan, robot, recordings, fitted_names)
    steps = run_steps(ident, robot, prepared, compared, plan.initial, plan.truth, draws.draws, plan.axes.force_per_amp)
    estimates = steps.estimates
    coef = estimates.coef
    W, _ = stack(*check_regression_data(np.concatenate([prepared[t].Y for t in fitted_names]),
                                        np.concatenate([prepared[t].tau_fit for t in fitted_names])))
    base = steps.base
    # the base step's factorisation of the same regressor, if it fitted every parameter on these data
    triangle = base.triangle if base is not None and base.fit.trajectories == tuple(fitted_names) else None
    analysis = BaseAnalysis.of(base_parameters(W, names, scale=np.maximum(np.abs(plan.initial), 1e-3),
                                               triangle=triangle))
    consistency = (consistent(ident.physical, robot, base.fit, base.equivalent, plan.initial, plan.truth)
                   if base is not None and ident.physical.enabled else None)
    records = steps.records
    if consistency is not None and consistency.failure is not None:     # the base step's record says why
        records = tuple(_with_failure(r, consistency.failure) if base is not None and r.name == base.fit.step else r
                        for r in records)
    consistent_set = consistency.consistent if consistency is not None else None
    fits = _fits(plan, robot, recordings, prepared, coef, None if base is None else base.equivalent,
                 None if consistent_set is None else consistent_set.values)
    table = ParameterTable(names=names, units=tuple(robot.parameter_unit(p) for p in names), initial=plan.initial,
                           identified=coef, sigma=estimates.sigma, lower=estimates.lower, upper=estimates.upper,
                           step=estimates.step_of, method=estimates.method_of, truth=plan.truth)
    used = {name: u.with_use(samples_used=len(prepared[name].t), rows_left_out=prepared[name].segments.left_out,
                             gaps=prepared[name].segments.gaps, stretches=len(prepared[name].segments.slices),
                             positions_not_in_counts=draws.uncounted.get(name, ()))
            for name, u in prepared_set.coverage.items()}
    results = Results(parameters=table, actuators=robot.actuator_names, actuator_kinds=robot.actuator_kinds,
                      fits=fits, steps=records, base_analysis=analysis, base_fit=None if base is None else base.fit,
                      rel_sigma_threshold=ident.rel_sigma_threshold, trajectories=used,
                      model_comparison=steps.model_comparison,
                      compared_label=None if ident.compare_with is None else ident.compare_with.label,
                      friction=choice.choice, consistent=consistent_set)
    evidence = axis_evidence(plan, robot, recordings, prepared, fitted_names, steps.fitted, draws.draws,
                             coef if base is None else base.equivalent)
    return _judged(results, verdict(results, plan.thresholds, plan.axes.force_per_amp, evidence))


def _judged(results: Results, quality: Verdict) -> Results:
    """``results`` with its quality verdict (a new record)."""
    return replace(results, quality=quality)


def _with_failure(record: StepRecord, failure: str) -> StepRecord:
    """A base step's record saying why no consistent parameters reproduce it (a new record)."""
    return replace(record, consistent=failure) if isinstance(record, BaseStep) else record


def _fits(plan: IdentificationPlan, robot: RobotModel, recordings: Mapping[str, Recording],
          prepared: Mapping[str, Prepared], coef: np.ndarray, base_equivalent: np.ndarray | None,
          consistent_values: np.ndarray | None) -> tuple[TrajectoryFit, ...]:
    """The forces along each prepared trajectory: measured, of the step-by-step values ``coef``,
    of the base fit (its ``base_equivalent`` vector), of the physically consistent parameters and
    of the set from elsewhere; a trajectory only a gains step uses (a payload run) is no fit of
    the model: the gains' figures say it all."""
    ident = plan.identification
    fitted_names = plan.fitted
    compared = compared_forces(plan, recordings, prepared, robot)
    rest = rest_speeds(plan, robot)
    payload_only = set(fitted_names) - {t for s in ident.steps if s.method != "gains" for t in s.trajectories}
    fits = []
    for name, p in prepared.items():
        if name in payload_only and name not in ident.validation:
            continue
        role = "validation" if name in ident.validation and name not in fitted_names else "identification"
        fits.append(TrajectoryFit(name, role, p.t, p.tau, p.Y @ coef, p.Theta, p.X,
                                  tau_base=None if base_equivalent is None else p.Y @ base_equivalent,
                                  moving=p.moving, tau_compared=compared.get(name), at_rest=np.abs(p.Thetad) < rest,
                                  tau_consistent=None if consistent_values is None else p.Y @ consistent_values))
    return tuple(fits)


def compared_forces(plan: IdentificationPlan, recordings: Mapping[str, Recording], prepared: Mapping[str, Prepared],
                    robot: RobotModel | None = None) -> dict[str, np.ndarray]:
    """Per prepared trajectory, the forces (N, a) the parameter set of ``identification.compare_with``
    predicts on its rows, with its own friction model, in the config's measure
    (:mod:`ident_hw.experiment.compared`; ``robot``: the identified robot, whose tree its model
    shares); ``{}`` without one."""
    spec = plan.identification.compare_with
    if spec is None:
        return {}
    logger.info(f"predicting with the parameters of {spec.label} ({spec.path})")
    other = compared_set(plan.robot, spec, robot)
    out = {}
    for name, own in prepared.items():
        theirs = prepare(plan, other.model, name, recordings[name])
        if len(theirs.t) != len(own.t):
            raise RecordingError(f"{name}: the compared model's rows ({len(theirs.t)}) are not the identified "
                                 f"model's ({len(own.t)})")
        out[name] = predicted_forces(other, theirs.Y, plan.axes.force_per_amp)
    return out
