"""The ``identification`` section: the steps, the data preparation, the online estimators, the
physically consistent step and the thresholds of the quality verdict."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Literal

from ident_hw.identification.least_squares import POORLY_IDENTIFIED_PERCENT

from .friction import FrictionKind
from .schema import in_range, non_negative, positive, spec


@dataclass(frozen=True)
class FilterConfig:
    """Data preparation: zero-phase Butterworth low-pass of the positions, parallel decimation.

    Defaults follow the sample rate and the motion ``bandwidth``
    (:meth:`ident_hw.filtering.FilterSettings.for_sample_rate`); ``cutoff`` and ``decimation``
    override them. ``position_margin``: the positions' low-pass, before they are differentiated,
    cuts off this many times above the band (at most a quarter of the sample rate,
    :attr:`ident_hw.filtering.FilterSettings.position_cutoff_hz`); default 2 for the paper's
    rest-to-rest paths and 1 for band-limited motions. The regressor, not linear in the motion,
    is computed from the low-passed positions, while the forces pass the same low-pass linearly:
    the two disagree where the forces have content near its cut-off. A robot whose forces reach
    the band's edge on any path (strongly non-linear kinematics, a drive's position loop near the
    band: the Delta) needs the positions low-passed well above it; the price is more of the
    encoders' rounding in the velocities and accelerations.
    """

    bandwidth: float = field(default=5.0, metadata=spec(positive, unit="Hz"))
    order: int = field(default=4, metadata=spec(in_range(1, 12)))
    cutoff: float | None = field(default=None, metadata=spec(positive, unit="Hz"))
    decimation: int | None = field(default=None, metadata=spec(in_range(1, 100)))
    position_margin: float | None = field(default=None, metadata=spec(in_range(1.0, 100.0)))


@dataclass(frozen=True)
class PayloadRunsConfig:
    """A known payload on the end-effector (``robot.described.end_effector``) during some of a
    step's trajectories: its ``mass`` (kg) is known, its centre of mass and inertia are not."""

    mass: float = field(metadata=spec(positive, unit="kg"))
    trajectories: tuple[str, ...] = ()


@dataclass(frozen=True)
class StepConfig:
    """One identification step: which recorded trajectories identify which parameters.

    ``sqp``: bounded fit of the listed parameters, the others held at their current values
    (the 3PRRR paper); the result is carried into the next steps. ``wls``/``ols``: least squares of the
    base parameters of the listed ones (the SVD-DLS paper; the others held), with their standard
    deviations (the power-model paper); reported beside the physical parameters, not carried on (a base
    parameter can group several physical ones). At most one step is ``wls``/``ols``. ``gains``: the
    drive gains (joint force per motor ampere) of every actuator with the base parameters of all the
    model's, from runs with and without a known ``payload`` (Gautier and Briot's global
    identification; :mod:`ident_hw.identification.drive_gains`), reported beside the config's.
    """

    name: str
    trajectories: tuple[str, ...]
    parameters: tuple[str, ...] = field(metadata=spec(
        doc="parameter names or shell-style patterns of them (leg?_rod.I*), or [all]: every parameter of the model"))
    method: Literal["sqp", "ols", "wls", "gains"] = "sqp"
    payload: PayloadRunsConfig | None = None


@dataclass(frozen=True)
class OnlineConfig:
    """The online estimators (SVD-DLS, beside RLS and damped RLS on the same data).

    They work on parameters divided by their ``scales`` and on forces divided by the noise of
    the outputs, so that ``threshold`` means the same for every direction (100 ⇔ a relative
    standard deviation of 10 % of the scale). Scales: ``scales`` per parameter name, friction
    kind (``fv_zeta`` ...) or drive term (``fv``), else the magnitude of the CAD value, else
    :data:`~ident_hw.config.scales.FRICTION_SCALES`, else (a body parameter) the largest CAD
    magnitude of its family (:data:`~ident_hw.config.scales.BODY_PARAMETER_FAMILIES`), by
    :func:`~ident_hw.config.to_identification.online_scales`.
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
        non_negative, doc="fitted parameters (physical or base) well identified (rel_sigma_threshold)"))
    max_force_lag: float = field(default=5e-4, metadata=spec(
        positive, unit="s", doc="delay of an axis's measured forces behind the model's (least squares over all "
                                "fitted trajectories): beyond it the data and the model disagree in time (a current "
                                "averaged by the drive identified as instantaneous: bus.current)"))
    max_axis_gain: float = field(default=2.0, metadata=spec(
        positive, unit="%", doc="how far an axis's forces stand from its own model, every fitted parameter refitted "
                                "with that axis's gain free (least squares over the rows the fits used): beyond it, "
                                "its torque constant, gear ratio or screw lead is likely off by about that much"))
    max_axis_rre: float = field(default=10.0, metadata=spec(
        positive, unit="%", doc="an axis's relative residual rre = 100 ||tau - tau_predicted|| / ||tau|| on each validation "
                                "trajectory (each identification one when there is none) over the samples where it moves, "
                                "of the identified parameters and of the physically consistent ones: beyond it the model "
                                "does not predict that axis (a current of the wrong sign, joint or gain, positions and "
                                "currents of different runs)"))
    min_lag_share: float = field(default=0.2, metadata=spec(
        in_range(0.0, 1.0), doc="a force lag beyond max_force_lag fails the verdict when it also accounts for at least "
                                "this share of the axis's residual (a time misalignment the data show); a smaller share "
                                "is a limit of the model beside a larger residual (a real joint's elasticity), noted"))
    max_residual_over_floor: float = field(default=5.0, metadata=spec(
        positive, doc="an axis's force residual (RMS over the rows the fits used, on any fitted trajectory, in the "
                      "drive's current) over what noise alone leaves it there: its current noise at standstill in "
                      "the same band (a 'standstill' trajectory of the campaign) and its encoders' rounding through "
                      "the identified model; without a standstill, not judged"))

    #: keys of earlier versions, and what became of them (the loader's message for a config that has one)
    RETIRED_KEYS: ClassVar[dict[str, str]] = {
        "max_axis_gain_spread": "replaced by max_axis_gain: each axis's gain is judged against its own model "
                                "refitted, no longer against the median of the axes with the same drive",
        "max_axis_residual_ratio": "removed: an axis's residual is judged against its own noise floor "
                                   "(max_residual_over_floor), no longer against its twins', which may differ "
                                   "in friction, rotor inertia and noise",
    }


@dataclass(frozen=True)
class PhysicalConfig:
    """The physically consistent parameters after the least-squares step
    (:mod:`ident_hw.identification.physical`): every body's mass, centre of mass and inertia
    realisable, friction and rotor inertia non-negative, nearest the CAD values in ``metric``,
    reproducing the identified base parameters within their covariance."""

    enabled: bool = field(default=True, metadata=spec(
        doc="compute them after the least-squares step (none without such a step)"))
    metric: Literal["euclidean", "entropic"] = field(default="entropic", metadata=spec(
        doc="distance to the CAD prior: scaled squares, or the log-determinant divergence of the bodies' "
            "pseudo-inertias (needs CAD bodies with positive-definite pseudo-inertias; others keep the squares)"))
    prior: float = field(default=1.0, metadata=spec(
        positive, doc="standard deviation of the CAD prior, in parameter scales: 1 = the CAD value is known to "
                      "about its own size; smaller trusts the CAD values more. Also what a CAD value a mass-fit "
                      "step holds is worth in its estimates' sigma"))
    scales: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class VectorConfig:
    """A named vector of a parameter file (``vector``) and, where it holds several values per
    body or actuator, the names of those values in its ``order``; ``model``: the friction model the
    vector's friction values belong to (``coulomb``: ``fc sign(qd)``)."""

    vector: str
    order: tuple[str, ...] = ()
    model: FrictionKind = "coulomb"


@dataclass(frozen=True)
class CompareWithConfig:
    """A parameter set from elsewhere (published, a CAD tool's, another identification), whose
    force prediction the report shows beside the identified one on every validation trajectory.

    ``path``: a text file of named vectors, ``name = [v1 v2 ...]`` (MATLAB's way of printing
    them); ``bodies``: the vector of the bodies' inertial values, ten per body of the description
    in its order, named in ``order`` (``m``, ``mx``, ``my``, ``mz`` (first moments), ``Ixx``,
    ``Ixy``, ``Ixz``, ``Iyy``, ``Iyz``, ``Izz``, about the joint frame); ``friction``: per actuator
    the values named in its ``order`` (``fv``, ``fc``, ``f0``) of its ``model``; ``rotor``: one
    rotor inertia per actuator; ``gains``: one drive gain per actuator, which its forces are
    measured with (joint force per motor ampere; default: the config's)."""

    path: str = field(metadata=spec(path=True))
    bodies: VectorConfig
    label: str = "compared"
    friction: VectorConfig | None = None
    rotor: VectorConfig | None = None
    gains: VectorConfig | None = None


@dataclass(frozen=True)
class IdentificationConfig:
    """Steps run in order (each fixes the parameters it identifies), validation trajectories,
    the SQP bounds ``[min, max]`` per parameter, the %σ above which an estimate is reported
    as poorly identified on its data, and the thresholds of the quality verdict."""

    steps: tuple[StepConfig, ...]
    validation: tuple[str, ...] = ()
    rel_sigma_threshold: float = field(default=POORLY_IDENTIFIED_PERCENT, metadata=spec(
        positive, unit="%", doc="estimates with a larger relative standard deviation are poorly identified (a base "
                                "parameter's sigma against the larger of its estimate and its physical size: "
                                "ident_hw.identification.physical_size)"))
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
    compare_with: CompareWithConfig | None = None
