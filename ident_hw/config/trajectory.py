"""The ``trajectories`` section: one entry per trajectory of the campaign, and the kinds of
trajectory with the keys each reads (:data:`KEYS_OF_KIND`, the one list of the kinds)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

from .schema import in_range, non_negative, positive, spec

#: the keys every trajectory may have
COMMON_KEYS = ("name", "kind", "cycles", "bandwidth", "online_only", "payload")
#: the kinds of trajectory, each with the further keys it reads: any other is refused (it would
#: be ignored). A kind added here is a value of ``trajectories[].kind`` (``TrajectoryKind``)
KEYS_OF_KIND = {
    "carriage_sweep": ("size", "speed_scale", "dwell"),
    "square": ("size", "rotation", "speed_scale", "dwell"),
    "triangle": ("speed_scale", "dwell"),
    "fourier": ("path",),
    "file": ("path",),
    "delta_training": ("duration", "fade", "amplitude"),
    "delta_verification": ("duration", "fade", "amplitude"),
    "delta_held_arm": ("duration", "fade", "amplitude"),
    "joint_excitation": ("duration", "fade", "amplitude", "harmonics", "seed", "path"),
    "standstill": ("duration",),
    "recorded": ("path", "rows", "window"),
}
#: the kinds that are recordings made elsewhere, read from their files (nothing is streamed)
RECORDED_KINDS = frozenset({"recorded"})
#: the kinds whose spectrum reaches the identification filter's band edge: the paper's
#: rest-to-rest paths (a jerk step at every vertex, short segments near the limits); their
#: positions are low-passed above the band by default (``ident_hw.experiment.plan.position_margin``)
REST_TO_REST_KINDS = frozenset({"carriage_sweep", "square", "triangle"})
#: s, a ``standstill`` trajectory's default duration: some 60 independent samples of the current
#: noise in a 15 Hz band, its RMS known to about 10 %
STANDSTILL_S = 2.0
#: s at the start of a standstill left out of the noise floor: the drives taking the load (a
#: robot that carries its weight sags onto its position loops as the brakes let go; its currents
#: swing by far more than their noise until the loops settle: docs/identification.md)
STANDSTILL_SETTLE = 0.5
#: s, the shortest standstill: as long again at rest after :data:`STANDSTILL_SETTLE`, of which the
#: identification filter's two ends (a quarter second each in a 15 Hz band) leave a little
STANDSTILL_MIN_S = 2 * STANDSTILL_SETTLE
# the type of TrajectoryConfig.kind: one of the kinds of KEYS_OF_KIND
if TYPE_CHECKING:     # a type checker sees text; the schema reads the kinds at run time
    TrajectoryKind = str
else:
    TrajectoryKind = Literal[tuple(KEYS_OF_KIND)]


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
    each actuator's limits and scaled by ``amplitude`` (one factor, or one per actuator);
    ``path``: the sines' frequencies, phases and weights from a file instead (an excitation
    optimised for the base regressor's condition, ``python -m ident_hw.experiment.excitation``).
    Any robot's ``standstill``: ``duration`` s (default :data:`STANDSTILL_S`) held at the home
    pose, the drives enabled: their currents at rest, the noise floor the quality verdict holds
    each axis's residual against (``identification.quality.max_residual_over_floor``).
    Any robot's ``recorded``: a recording the tool did not make (``path``, a CSV file read as the
    ``recordings`` section says), identified by ``ident-hw identify`` (nothing is streamed);
    ``rows`` ``[first, last]`` (data rows, 1-based, inclusive) or ``window`` ``[start, end]`` (s,
    in the file's own time) picks the part to use; idle rows at its head and tail are left out
    either way. ``path`` may name an environment variable, ``${IDENT_HW_DATASETS}/...``.
    ``online_only``: streamed only for the online estimators (``ident-hw online``, or ``run``
    with ``identification.online.in_run``), after the others; otherwise ``run`` leaves it out. ``payload``: on the in-process simulated rig, a payload added during this trajectory
    (:class:`PayloadConfig`), e.g. on an ``online_only`` one for the online estimators to track.
    A key the trajectory's kind does not read (:data:`KEYS_OF_KIND`, :data:`COMMON_KEYS`) is
    refused rather than ignored.
    """

    name: str
    kind: TrajectoryKind
    size: float | None = field(default=None, metadata=spec(positive, unit="m"))
    rotation: float = field(default=0.0, metadata=spec(unit="rad", angle=True))
    speed_scale: float = field(default=1.0, metadata=spec(in_range(0.01, 1.0)))
    dwell: float = field(default=0.0, metadata=spec(non_negative, unit="s"))
    cycles: int = field(default=1, metadata=spec(in_range(1, 1000)))
    path: str | None = field(default=None, metadata=spec(path=True, doc="relative to the file that writes it"))
    bandwidth: float | None = field(default=None, metadata=spec(positive, unit="Hz"))
    duration: float | None = field(default=None, metadata=spec(positive, unit="s"))
    fade: float = field(default=1.0, metadata=spec(non_negative, unit="s"))
    amplitude: float | tuple[float, ...] = field(default=1.0, metadata=spec(in_range(0.01, 10.0)))
    online_only: bool = False
    payload: PayloadConfig | None = None
    harmonics: int = field(default=5, metadata=spec(in_range(1, 50)))
    seed: int = 0
    rows: tuple[int, int] | None = field(default=None, metadata=spec(
        in_range(1, 10**9), doc="[first, last] data rows of a recorded file, 1-based, inclusive"))
    window: tuple[float, float] | None = field(default=None, metadata=spec(
        unit="s", doc="[start, end] of a recorded file, in its own time"))

    @property
    def recorded(self) -> bool:
        """A recording made elsewhere (:data:`RECORDED_KINDS`), read from its file."""
        return self.kind in RECORDED_KINDS
