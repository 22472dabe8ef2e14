"""The identification steps of ``identification.steps``, in their order (:func:`run_steps`).

Each ``sqp`` step is the paper's bounded SQP mass fit of its parameters with the others held at
their current values (CAD at the start), so the sweep's ``m_c`` is used by the squares' step
(:func:`fit_sqp_step`). A ``wls``/``ols`` step fits the base parameters of its parameters
(:func:`fit_base`), reported beside the physical ones with its own prediction of every
trajectory; its physically consistent parameters follow (:func:`consistent`). A ``gains`` step
fits the drive gains from runs with and without a payload (:func:`fit_gains_step`). Each step's
σ holds what :mod:`ident_hw.experiment.uncertainty` adds to the least-squares one (the encoders'
resolution, the values the step holds).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ident_hw.config.identification import IdentificationConfig, PhysicalConfig, StepConfig
from ident_hw.config.scales import drive_term
from ident_hw.config.schema import FieldError
from ident_hw.config.to_identification import physical_scales, step_parameters
from ident_hw.identification.base_params import Triangle, column_scale, identify_base, on_kept, scaled_condition
from ident_hw.identification.drive_gains import GainsRun, fit_gains
from ident_hw.identification.least_squares import LeastSquaresResult, check_regression_data, compensated, stack, wls
from ident_hw.identification.mass_fit import sqp_fit
from ident_hw.identification.model_comparison import ModelComparison, ModelRows, compare_models
from ident_hw.identification.physical import ConsistencyError, ConsistentSet, consistent_parameters
from ident_hw.identification.physical_size import combination_sizes, parameter_sizes
from ident_hw.model.base_basis import BaseBasis
from ident_hw.model.interface import RobotModel
from ident_hw.records import BaseStep, DriveGainsFigures, GainsStep, MassFitStep, SkippedStep, StepRecord
from ident_hw.results import BaseFit

from .encoder import spread_covariance
from .preparation import Prepared
from .uncertainty import EncoderSpread, encoder_spread, held_value_sigma, refit

logger = logging.getLogger(__name__)

#: one step's data with the encoders read again: (Y (N, a, n), tau (N, a)) per draw
Draw = tuple[np.ndarray, np.ndarray]


@dataclass(frozen=True)
class Estimates:
    """The physical parameters as the steps leave them (arrays (n,), read-only): values, sigma
    (NaN: none), bounds, and which step and method fitted each (``""``: held at its initial
    value). A step's fit makes a new one (:meth:`fitted`)."""

    coef: np.ndarray
    sigma: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    step_of: tuple[str, ...]
    method_of: tuple[str, ...]

    @classmethod
    def initial(cls, values: np.ndarray) -> Estimates:
        """Every parameter at its initial (CAD) value, nothing fitted."""
        n = len(values)
        return cls(_read_only(values), _read_only(np.full(n, np.nan)), _read_only(np.full(n, -np.inf)),
                   _read_only(np.full(n, np.inf)), ("",) * n, ("",) * n)

    def fitted(self, coef: np.ndarray, idx: Sequence[int], sigma: np.ndarray | None,
               bounds: Sequence[tuple[float, float]], step: str, method: str) -> Estimates:
        """These estimates after a step that left every value at ``coef`` (n,) and fitted the
        parameters ``idx``, with their ``sigma`` (len(idx),; None: unchanged) and ``bounds``."""
        idx = list(idx)
        new_sigma, lower, upper = self.sigma.copy(), self.lower.copy(), self.upper.copy()
        if sigma is not None:
            new_sigma[idx] = sigma
        step_of, method_of = list(self.step_of), list(self.method_of)
        for k, i in enumerate(idx):
            lower[i], upper[i] = bounds[k]
            step_of[i], method_of[i] = step, method
        return Estimates(_read_only(coef), _read_only(new_sigma), _read_only(lower), _read_only(upper),
                         tuple(step_of), tuple(method_of))


def _read_only(values: np.ndarray) -> np.ndarray:
    out = np.array(values, dtype=float)
    out.flags.writeable = False
    return out


def held_value_std(estimates: Estimates, prior_std: np.ndarray) -> np.ndarray:
    """(n,) what each parameter is worth as a value a mass-fit step holds: the sigma of the step
    that fitted it (``estimates``), else (its
    initial, CAD value, still) ``prior_std`` (n,), the CAD prior of the config
    (``identification.physical.prior`` scales)."""
    fitted = np.array([bool(s) for s in estimates.step_of]) & np.isfinite(estimates.sigma)
    return np.where(fitted, estimates.sigma, prior_std)


@dataclass(frozen=True)
class BaseStepFit:
    """A least-squares step of base parameters (:func:`fit_base`): its :class:`BaseFit`, the
    physical vector (n,) that predicts the same forces (``equivalent``: each kept parameter
    carries its base value, the eliminated ones 0, the held ones their values) and the step's record."""

    fit: BaseFit
    equivalent: np.ndarray
    record: BaseStep
    #: the factorised regressor of the step's data (every parameter free; None when it held some),
    #: for the base parameters of the same data at another scale (``base_parameters(triangle=)``)
    triangle: Triangle | None = None


def fit_base(step: StepConfig, free_names: Sequence[str], names: tuple[str, ...], Y: np.ndarray, tau: np.ndarray,
             coef: np.ndarray, initial: np.ndarray, truth: np.ndarray | None, threshold: float,
             basis: BaseBasis | None = None, draws: Sequence[Draw] = (), sizes: np.ndarray | None = None) -> BaseStepFit:
    """Least squares (``step.method`` ``wls``/``ols``) of the base parameters of ``free_names``
    on ``Y`` (N, a, n), ``tau`` (N, a), the other parameters (``names``, n) held at ``coef``;
    ``basis``: the model's readable base parameters (``RobotModel.readable_base``), used when
    every parameter is free and the data identifies them all. ``draws``: the same data with the
    encoders read again (:mod:`ident_hw.experiment.encoder`), each fitted on the same columns
    with the same weights; the covariance of their estimates joins the least-squares one, and
    the spread of their regressors corrects the estimate for the encoders' noise in the
    regressor (:func:`ident_hw.identification.least_squares.compensated`; the record's
    ``encoder_shift``). ``sizes`` (n,): the parameters' physical sizes
    (:func:`ident_hw.identification.physical_size.parameter_sizes`), which judge with the
    threshold whether a base parameter is well identified (None: its %σ alone)."""
    free = [names.index(p) for p in free_names]
    held = [i for i in range(len(names)) if i not in free]
    Yf = Y[:, :, free]
    tau_free = tau - Y[:, :, held] @ coef[held]       # the forces the free parameters must explain
    scale = column_scale(Yf)
    triangle = Triangle.of(stack(*check_regression_data(Yf, tau_free))[0], scale)
    base, fit = identify_base(Yf, tau_free, tuple(free_names), scale=scale,
                              weighted=step.method == "wls", basis=None if held else basis, triangle=triangle)
    H = np.zeros((base.rank, len(names)))
    H[:, free] = np.where(np.abs(base.H) > 1e-10, base.H, 0.0)   # rounding of N1 N2^-1, not a coefficient
    kept = [free[list(free_names).index(k)] for k in base.kept]
    plain = fit.coef
    fit = compensated(fit, Y[:, :, kept], tau_free, [Yk[:, :, kept] for Yk, _ in draws])
    equivalent = np.array(coef, dtype=float)
    equivalent[free] = on_kept(tuple(free_names), base.kept, fit.coef)
    encoder = spread_covariance([refit(fit, Yk[:, :, kept], tauk - Yk[:, :, held] @ coef[held])
                                 for Yk, tauk in draws], len(kept))
    covariance = fit.covariance + encoder
    result = BaseFit(step=step.name, method=fit.method, trajectories=tuple(step.trajectories),
                     expressions=base.expressions, H=H, coef=fit.coef, sigma=np.sqrt(np.diag(covariance)),
                     initial=H @ initial, truth=None if truth is None else H @ truth,
                     held=tuple(names[i] for i in held), unexcited=base.unexcited, threshold=threshold,
                     covariance=covariance, size=None if sizes is None else combination_sizes(H, sizes))
    spread = encoder_spread(draws, encoder)
    record = BaseStep(name=step.name, trajectories=tuple(step.trajectories), free=tuple(free_names),
                      method=fit.method, eliminated=tuple(base.eliminated), **_least_squares_figures(fit),
                      cond_scaled=triangle.scaled_condition([list(free_names).index(k) for k in base.kept]),
                      encoder_draws=spread.draws,
                      encoder_sigma=spread.sigma,
                      encoder_shift=tuple((fit.coef - plain).tolist()) if len(draws) > 1 else ())
    every = free == list(range(len(names)))        # the triangle is then of the whole regressor's columns
    return BaseStepFit(result, equivalent, record, triangle if every else None)


def _least_squares_figures(fit: LeastSquaresResult) -> dict:
    """The :class:`BaseStep` fields of a least-squares fit's figures (the estimates are the BaseFit's)."""
    return dict(sigma2=float(fit.sigma2), cond=float(fit.cond), covariance=fit.covariance_method,
                residual_rms=tuple(fit.residual_rms.tolist()),
                output_std=None if fit.output_std is None else tuple(fit.output_std.tolist()),
                poorly_identified=tuple(fit.poorly_identified))


def comparison(step: StepConfig, free_names: Sequence[str], names: tuple[str, ...], Y: np.ndarray, tau: np.ndarray,
               prepared: Mapping[str, Prepared], coef: np.ndarray, truth: np.ndarray | None, weighted: bool,
               threshold: float, basis: BaseBasis | None = None) -> ModelComparison:
    """The dynamic, power and energy models' base parameters of the least-squares ``step``
    (:func:`ident_hw.identification.model_comparison.compare_models`): the dynamic model on the
    step's own rows ``Y`` (N, a, n), ``tau`` (N, a), the power and energy models on the rows
    :func:`ident_hw.experiment.preparation.prepare` made of the same stretches; parameters
    outside ``free_names`` held at ``coef`` (n,), as in :func:`fit_base`."""
    rows = [ModelRows("dynamic", Y, tau)]
    for model in ("power", "energy"):
        parts = [getattr(prepared[t], model) for t in step.trajectories if getattr(prepared[t], model) is not None]
        if parts:
            rows.append(ModelRows.concatenate(parts))
    return compare_models(names, rows, free=free_names, values=coef, truth=truth, weighted=weighted,
                          basis=basis, step=step.name, trajectories=step.trajectories, threshold=threshold)


def excited_parameters(free_names: Sequence[str], names: tuple[str, ...], Y: np.ndarray, tau: np.ndarray) -> list[str]:
    """The parameters of ``free_names`` whose regressor column is not zero throughout the rows
    the fit uses (``Y`` (N, a, n), ``tau`` (N, a), NaN where an axis is left out)."""
    rows, _ = stack(*check_regression_data(Y, tau))
    return [p for p in free_names if np.any(rows[:, names.index(p)] != 0)]


@dataclass(frozen=True)
class MassFit:
    """An SQP step's outcome (:func:`fit_sqp_step`): its record, the estimates after it and the
    parameters it fitted (none when it was skipped)."""

    record: MassFitStep | SkippedStep
    estimates: Estimates
    excited: tuple[str, ...]


def fit_sqp_step(step: StepConfig, free_names: Sequence[str], names: tuple[str, ...], Y: np.ndarray,
                 tau: np.ndarray, estimates: Estimates, all_bounds: Mapping[str, tuple[float, float]],
                 prepared: Mapping[str, Prepared], draws: Sequence[Draw] = (),
                 held_std: np.ndarray | None = None) -> MassFit:
    """The paper's bounded SQP mass fit of one step's parameters on its data (``Y`` (N, a, n),
    ``tau`` (N, a)), the others held at their values in ``estimates``. ``draws``: the step's data
    with the encoders read again (:func:`fit_base`); the spread of their estimates joins each
    sigma. ``held_std`` (n,): what each value the step holds is worth
    (:func:`held_value_std`); what they are worth in each estimate
    (:func:`ident_hw.experiment.uncertainty.held_value_sigma`) joins its sigma too. A parameter
    its rows do not excite at all (a carriage whose every stretch was left out) is held, and the
    record says so."""
    excited = excited_parameters(free_names, names, Y, tau)
    unexcited = [p for p in free_names if p not in excited]
    if not excited:
        return MassFit(SkippedStep(step.name, tuple(step.trajectories),
                                   skipped=f"none of {', '.join(step.parameters)} excited by its data"),
                       estimates, ())
    bounds = {p: all_bounds[p] for p in excited if p in all_bounds}
    fit = sqp_fit(Y, tau, names, estimates.coef, free=excited, bounds=bounds)
    coef = fit.coef
    idx = [names.index(p) for p in excited]
    held = [i for i in range(len(names)) if i not in idx]
    sigma, statistics, spread, cond_W, held_sigma = None, None, EncoderSpread(), None, ()
    # sigma of the free parameters: WLS statistics of the same weighted problem
    try:
        stats = wls(Y[:, :, idx], tau - Y[:, :, held] @ coef[held], excited, output_std=fit.output_std)
    except ValueError as exc:  # rank deficient: the fit is bounded, but has no covariance
        statistics = str(exc)
    else:
        encoder = spread_covariance([refit(stats, Yk[:, :, idx], tauk - Yk[:, :, held] @ coef[held])
                                     for Yk, tauk in draws], len(idx))
        from_held = (held_value_sigma(stats, Y, tau, idx, held, held_std[held]) if held_std is not None
                     else np.zeros(len(idx)))
        sigma = np.sqrt(stats.std ** 2 + np.diag(encoder) + from_held ** 2)
        spread, cond_W = encoder_spread(draws, encoder), stats.cond
        if held_std is not None:
            held_sigma = tuple(from_held.tolist())
    record = MassFitStep(
        name=step.name, trajectories=tuple(step.trajectories), method=fit.method, free=tuple(fit.free),
        parameters={nm: float(v) for nm, v in zip(fit.names, fit.coef)},
        parameters_lsq_linear={nm: float(v) for nm, v in zip(fit.names, fit.coef_lsq)},
        max_rel_difference=float(fit.max_rel_difference), cost=float(fit.cost),
        residual_rms=tuple(fit.residual_rms.tolist()), output_std=tuple(fit.output_std.tolist()),
        iterations=int(fit.iterations), success=bool(fit.success), message=fit.message, at_bounds=tuple(fit.at_bounds),
        rows_left_out={t: prepared[t].segments.left_out for t in step.trajectories},
        cond_scaled=scaled_condition(Y[:, :, idx], tau), unexcited=tuple(unexcited), statistics=statistics,
        encoder_draws=spread.draws, encoder_sigma=spread.sigma, held_sigma=held_sigma, cond_W=cond_W)
    after = estimates.fitted(coef, idx, sigma, [bounds.get(p, (0.0, np.inf)) for p in excited], step.name,
                             step.method)
    return MassFit(record, after, tuple(excited))


def fit_gains_step(step: StepConfig, robot: RobotModel, prepared: Mapping[str, Prepared],
                   configured: np.ndarray) -> GainsStep:
    """A ``gains`` step: the drive gains of every actuator with the base parameters of all the
    model's, from the step's runs with and without its payload (:mod:`ident_hw.identification.drive_gains`),
    started from (and reported beside) the config's force per ampere ``configured`` (a,). The
    estimates of the other steps are not changed: a gain the user trusts goes into the config."""
    per_amp = np.asarray(configured, dtype=float)
    from ident_hw.model.described import DescribedRobot      # pinocchio: described robots only
    if not isinstance(robot, DescribedRobot):    # the config's check refuses a gains step of another robot
        raise ValueError(f"step {step.name}: a gains step needs a described robot's model (its payload's columns)")
    payload = list(robot.payload_indices())
    if step.payload is None:
        raise ValueError(f"step {step.name}: a gains step needs its payload runs")
    runs = [GainsRun(prepared[t].Y, prepared[t].tau_fit / per_amp,
                     prepared[t].Y[:, :, payload] if t in step.payload.trajectories else None)
            for t in step.trajectories]
    fit = fit_gains(runs, step.payload.mass, per_amp)
    mass = np.concatenate([run.payload[:, :, 0] for run in runs if run.payload is not None])
    reach = np.sqrt(np.mean(mass ** 2, axis=0))           # N·m (N) per kg of payload, RMS
    figures = DriveGainsFigures(gains=tuple(fit.gains.tolist()), sigma=tuple(fit.sigma.tolist()),
                                configured=tuple(per_amp.tolist()), residual_rms=tuple(fit.residual_rms.tolist()),
                                residual_rms_configured=tuple(fit.residual_rms_start.tolist()),
                                payload_mass=step.payload.mass, payload_trajectories=tuple(step.payload.trajectories),
                                rank=fit.rank, blocks=fit.blocks,
                                mass_axes=tuple(a for a, r in zip(robot.actuator_names, reach) if r > 1e-6 * reach.max()))
    logger.info("  drive gains " + ", ".join(f"{a} {g:.4g} (sigma {s:.2g}; config {c:.4g})" for a, g, s, c in
                                             zip(robot.actuator_names, fit.gains, fit.sigma, per_amp)))
    return GainsStep(step.name, tuple(step.trajectories), method="gains",
                     free=tuple(f"g_{a}" for a in robot.actuator_names), drive_gains=figures)


@dataclass(frozen=True)
class StepsOutcome:
    """What the steps did (:func:`run_steps`): each step's record in order, the physical
    estimates they leave, the last base step's fit and its equivalent physical vector (n,)
    (None without a base step), the model comparison (None: not asked) and the parameters some
    step fitted."""

    records: tuple[StepRecord, ...]
    estimates: Estimates
    base: BaseStepFit | None
    model_comparison: ModelComparison | None
    fitted: frozenset[str]


def _step_data(step: StepConfig, prepared: Mapping[str, Prepared]) -> Draw:
    return (np.concatenate([prepared[t].Y for t in step.trajectories]),
            np.concatenate([prepared[t].tau_fit for t in step.trajectories]))


def run_steps(ident: IdentificationConfig, robot: RobotModel, prepared: Mapping[str, Prepared],
              compared: Sequence[str], initial: np.ndarray, truth: np.ndarray | None,
              draws: Sequence[Mapping[str, Prepared]] = (), force_per_amp: np.ndarray | None = None
              ) -> StepsOutcome:
    """Runs the identification steps in their order, each on the parameters the ones before left,
    from the CAD values ``initial`` (n,), and the model comparison on the base step's data when
    ``compared`` names its trajectories; ``draws``: the recordings with the encoders read again
    (:func:`ident_hw.experiment.uncertainty.reread_draws`), whose spread joins each step's sigma. A
    mass-fit step's sigma has also what the values it holds are worth: an earlier step's sigma,
    else the CAD prior (``identification.physical.prior`` scales of each parameter,
    :func:`held_value_std`); ``force_per_amp`` (a,): the config's,
    what a ``gains`` step starts from."""
    names = robot.parameter_names
    records: list[StepRecord] = []
    estimates = Estimates.initial(initial)
    base: BaseStepFit | None = None
    model_comparison = None
    fitted: set[str] = set()            # every parameter some step fitted
    prior_std = None
    if any(s.method == "sqp" for s in ident.steps):
        prior_std = ident.physical.prior * np.array(physical_scales(ident.physical, names, initial))
    for step in ident.steps:
        free_names = step_parameters(step, names)
        logger.info(f"step {step.name}: fitting "
                    + ("all parameters" if step.parameters == ("all",) else ", ".join(free_names))
                    + (f" (base parameters, {step.method.upper()})" if step.method != "sqp" else ""))
        Y, tau = _step_data(step, prepared)
        if not len(Y):
            records.append(SkippedStep(step.name, tuple(step.trajectories),
                                       skipped="no stretch of its recordings could be filtered"))
            continue
        step_draws = [_step_data(step, d) for d in draws]
        if step.method == "gains":
            if force_per_amp is None:
                raise ValueError(f"step {step.name}: a gains step needs the actuators' force per ampere")
            records.append(fit_gains_step(step, robot, prepared, force_per_amp))
            continue
        if step.method == "sqp":
            mass = fit_sqp_step(step, free_names, names, Y, tau, estimates, ident.bounds, prepared, step_draws,
                                None if prior_std is None else held_value_std(estimates, prior_std))
            records.append(mass.record)
            estimates = mass.estimates
            fitted.update(mass.excited)
            continue
        base = fit_base(step, free_names, names, Y, tau, estimates.coef, initial, truth,
                        ident.rel_sigma_threshold, robot.readable_base(), step_draws,
                        parameter_sizes(robot.physical_bodies(), initial))
        records.append(base.record)
        fitted.update(free_names)
        if compared:
            logger.info(f"step {step.name}: the dynamic, power and energy models' base parameters")
            model_comparison = comparison(step, free_names, names, Y, tau, prepared, estimates.coef, truth,
                                          step.method == "wls", ident.rel_sigma_threshold, robot.readable_base())
    return StepsOutcome(tuple(records), estimates, base, model_comparison, frozenset(fitted))


@dataclass(frozen=True)
class Consistency:
    """The physically consistent parameters of a base fit (:func:`consistent`): the set, or None
    and ``failure``: why there is none."""

    consistent: ConsistentSet | None
    failure: str | None = None


def consistent(physical: PhysicalConfig, robot: RobotModel, base_fit: BaseFit, equivalent: np.ndarray,
               initial: np.ndarray, truth: np.ndarray | None) -> Consistency:
    """The physical parameters nearest the CAD values ``initial`` (n,) that reproduce
    ``base_fit`` (:func:`ident_hw.identification.physical.consistent_parameters`, with the
    ``identification.physical`` settings); the parameters the base step held keep their values in
    ``equivalent`` (n,). None and the reason when there is no such set."""
    logger.info(f"step {base_fit.step}: the physically consistent parameters nearest the CAD values")
    names = robot.parameter_names
    held = {names.index(p): float(equivalent[names.index(p)]) for p in base_fit.held}
    # a drive term without a CAD value (friction) is scaled by its least-squares value, or where the
    # data left it at 0 (a rotor inertia merged into its link's) by the largest of its kind
    bodies = robot.physical_bodies()
    in_body = {i for body in bodies for i in body.indices}
    typical = np.array([abs(equivalent[i]) if i not in in_body and not initial[i] else initial[i]
                        for i in range(len(names))])
    for i, p in enumerate(names):
        if i not in in_body and not typical[i]:
            kin = [abs(equivalent[j]) for j, q in enumerate(names) if j not in in_body and drive_term(q) == drive_term(p)]
            typical[i] = max(kin, default=0.0)
    try:
        scale = np.array(physical_scales(physical, names, typical))
        # an offset and a Stribeck term have either sign (the Stribeck term: the friction dips or rises near rest)
        signed = [i for i, p in enumerate(names) if drive_term(p) in ("f0", "fs")]
        if base_fit.covariance is None:
            raise ConsistencyError("the base fit has no covariance (read from a folder)")
        return Consistency(consistent_parameters(names, tuple(robot.parameter_unit(p) for p in names), base_fit.H,
                                                 base_fit.coef, base_fit.covariance, initial, scale, bodies, held=held,
                                                 metric=physical.metric, prior_relative=physical.prior, truth=truth,
                                                 signed=signed))
    except (ConsistencyError, FieldError) as exc:
        return Consistency(None, str(exc))
