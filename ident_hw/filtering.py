"""Signal preparation for identification: zero-phase low-pass, central differences, parallel
filtering and decimation (the power-model paper, sec. 5).

All arrays are time-major: axis 0 is the sample index. Times in s, frequencies in Hz.

The chain used by :func:`ident_hw.experiment.preparation.prepare` (stretch by stretch) is

1. ``lowpass`` of the measured positions (zero phase, Butterworth, ``sosfiltfilt``);
2. ``central_derivatives`` of the filtered positions (velocities, accelerations);
3. the regressor is built sample by sample from these;
4. ``through_position_lowpass``: the torques and the Coulomb columns through the low-pass of
   step 1 too (the rest of the regressor passed it with the positions);
5. ``parallel_decimate`` applies one and the same zero-phase low-pass and decimation to the
   torques and to every regressor column, and trims the filter edges.

Because the filter of step 5 is linear and identical for both sides, ``tau = Y pi`` still
holds exactly after it: parallel filtering removes noise without biasing the estimate.

A recording is filtered stretch by stretch (:mod:`ident_hw.segments`), and a stretch ends
either at the recording's own first or last row or at a *cut* inside it (a skipped SYNC slot, a
row without data): :class:`Ends`. At a recording's end the filters reflect the data as
``sosfiltfilt`` does (odd) and the stretch loses ``FilterSettings.trim`` rows there, three
periods of the cut-off (the robot is at rest at a trajectory's ends: nothing is lost there). A
cut, which may fall anywhere in the motion, costs only what the filters need
(:attr:`FilterSettings.cut_trim`, the half-width of their main lobe): the positions are extended
past the cut by the least-squares quartic of the rows next to it (:data:`POLYNOMIAL`), which
follows the motion's acceleration and jerk where the odd reflection flips the acceleration, and
the parallel filter mirrors the rows (:data:`EVEN`), which keeps the noise of the rows next to
the cut averaged where the odd reflection hands the first row's noise through unfiltered. Both
extensions are linear in the data and built from the stretch's own rows only: nothing reaches
across the cut.

Forces from the drives' averaged currents have been through a filter already, the drives'
running average; :func:`running_average` puts the regressor through the same one before steps 4 and 5.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


#: :attr:`FilterSettings.position_margin` for a motion whose spectrum reaches the band edge
POSITION_MARGIN = 2.0


@dataclass(frozen=True)
class FilterSettings:
    """Filtering and decimation settings (defaults from :meth:`for_sample_rate`).

    Attributes:
        sample_rate: input sample rate in Hz.
        cutoff_hz: cut-off of the identification's band, Hz: of the parallel filter (at most,
            :attr:`decimation_cutoff_hz`) and, with ``position_margin`` 1, of the positions'
            low-pass too.
        order: Butterworth order (the zero-phase filter has twice this order).
        decimation: keep one sample in ``decimation`` after the parallel filter.
        trim: samples dropped at each end (input rate), where the zero-phase filters and
            the one-sided differences at the edges are not trustworthy.
        position_margin: the positions' low-pass cuts off this many times above the parallel
            filter (:attr:`position_cutoff_hz`; >= 1): :data:`POSITION_MARGIN` for a motion whose
            spectrum reaches the band edge.
    """

    sample_rate: float
    cutoff_hz: float
    order: int = 4
    decimation: int = 1
    trim: int = 0
    position_margin: float = 1.0

    def __post_init__(self) -> None:
        nyquist = 0.5 * self.sample_rate
        if not self.sample_rate > 0:
            raise ValueError(f"sample_rate must be positive, got {self.sample_rate}")
        if not 0 < self.cutoff_hz < nyquist:
            raise ValueError(f"cutoff_hz must lie in (0, {nyquist:g}) Hz (Nyquist), got {self.cutoff_hz}")
        if self.order < 1 or self.decimation < 1 or self.trim < 0:
            raise ValueError(f"order and decimation must be >= 1 and trim >= 0, got {self}")
        if not self.position_margin >= 1.0:
            raise ValueError(f"position_margin must be >= 1, got {self.position_margin}")

    @classmethod
    def for_sample_rate(cls, sample_rate: float, bandwidth_hz: float = 5.0, order: int = 4) -> "FilterSettings":
        """Defaults for a sample rate, given the bandwidth of the motion (Hz).

        Cut-off ten times the motion bandwidth (and at most a quarter of the sample rate),
        decimation so that the decimated Nyquist frequency is 1.25 × the cut-off, trim of
        three periods of the cut-off at each end. At 1 kHz and 5 Hz: 50 Hz, 8, 60 samples.

        Why, in numbers (1 kHz, 2048-count encoders, tests/test_ident_noise.py): the cut-off
        trades two errors. Too close to the motion, the filter distorts the positions (the
        order-4 zero-phase Butterworth changes a component at ``r = f/f_c`` by about
        ``r^8``: 1e-8 at ten times the bandwidth). Too far, the encoder quantisation,
        differentiated twice, enters the regressor as acceleration noise whose variance grows
        as ``f_c^5`` (at 50 Hz it was the main residual on the link torques, ten times the
        current noise; at 13 Hz it is below it). So the bandwidth to give is the highest
        frequency the motion really has; the paper's rest-to-rest trajectories are broadband
        (jerk steps): at 5 Hz the force distortion on noise-free data is 0.04 % (triangle,
        sweep) to 0.3 % (squares, 0.3 s segments at 27 rad/s²) RMS. The
        decimation puts the new Nyquist frequency just above the cut-off, so the decimated
        residual is close to white; what correlation is left is accounted for by the HAC
        covariance of :mod:`ident_hw.identification.least_squares`.
        """
        cutoff = min(10.0 * bandwidth_hz, 0.25 * sample_rate)
        decimation = max(1, int(sample_rate // (2.5 * cutoff)))
        trim = math.ceil(3.0 * sample_rate / cutoff)
        return cls(sample_rate=sample_rate, cutoff_hz=cutoff, order=order, decimation=decimation, trim=trim)

    @property
    def decimation_cutoff_hz(self) -> float:
        """Cut-off of the anti-alias filter applied before decimation: 0.8 × the new Nyquist."""
        if self.decimation == 1:
            return self.cutoff_hz
        return min(self.cutoff_hz, 0.8 * 0.5 * self.sample_rate / self.decimation)

    @property
    def position_cutoff_hz(self) -> float:
        """Cut-off of the positions' low-pass (:func:`prepare_actuated`), Hz: ``position_margin``
        times the parallel filter's cut-off (:attr:`decimation_cutoff_hz`), at most a quarter of
        the sample rate, never below :attr:`cutoff_hz` (which it is with a margin of 1).

        Why above the parallel filter, for some motions: the regressor passes the positions'
        low-pass with the positions, the forces (and the Coulomb columns) pass it by
        :func:`through_position_lowpass`; the two agree where the regressor is linear in the
        motion, and differ by its curvature where it is not, most at the band's edge, where the
        paper's rest-to-rest paths (a jerk step at every vertex, short segments) have force. Twice
        the parallel filter's cut-off leaves the positions' low-pass within 0.4 % of unity
        (``1 / (1 + 2^-8)``) over the band the fit sees; the price is more of the encoder's
        rounding in the accelerations, which is why it is not used everywhere.
        """
        return max(self.cutoff_hz, min(self.position_margin * self.decimation_cutoff_hz, 0.25 * self.sample_rate))

    @property
    def output_rate(self) -> float:
        """Sample rate after decimation, Hz."""
        return self.sample_rate / self.decimation

    @property
    def cut_trim(self) -> int:
        """Samples (input rate) a stretch loses at a cut inside a recording: the half-width of the
        main lobe of the wider of its two filters (:func:`lobe_width`; 13 at 250 Hz and a 10 Hz
        cut-off, 9 at 15 Hz). From there on a filtered sample weighs the stretch's own rows with
        its whole main lobe; what the extensions past the cut (:class:`Ends`) contribute is the
        filters' side lobes, on a polynomial continuation of the motion and mirrored noise."""
        return max(lobe_width(self.sample_rate, self.cutoff_hz, self.order),
                   lobe_width(self.sample_rate, self.decimation_cutoff_hz, self.order))

    def trims(self, ends: "Ends") -> tuple[int, int]:
        """Samples dropped at the start and at the end of a stretch with ``ends``: :attr:`trim`
        at a recording's own end, :attr:`cut_trim` at a cut."""
        return ends.pick(self.cut_trim, self.trim)


#: how a zero-phase filter extends a stretch past one of its ends (:func:`lowpass`): ``ODD``
#: ``sosfiltfilt``'s odd reflection (``2 x[0] - x[k]``), ``EVEN`` the mirror image (``x[k]``),
#: both over ``sosfiltfilt``'s default pad length; ``POLYNOMIAL`` the least-squares polynomial of
#: degree :data:`EXTENSION_DEGREE` through the ``2 lobe_width`` rows next to the end (the
#: filter's main lobe, both sides), over :func:`settling_length` samples
ODD, EVEN, POLYNOMIAL = "odd", "even", "polynomial"
#: degree of the ``POLYNOMIAL`` extension: a quartic follows the motion's acceleration, jerk and
#: snap across the cut; how the degree was chosen: docs/drives.md, *Data kept on a lossy bus*
EXTENSION_DEGREE = 4


@dataclass(frozen=True)
class Ends:
    """Where a stretch of samples begins (``head_cut``) and ends (``tail_cut``): True at a cut
    inside a recording (a skipped SYNC slot, a row without data), False at the recording's own
    first or last row. See the module docstring for what each costs."""

    head_cut: bool = False
    tail_cut: bool = False

    def pick(self, at_cut, at_end) -> tuple:
        """``(start, end)`` of a stretch with these ends: ``at_cut`` where it ends at a cut,
        ``at_end`` where at a recording's own end (rows trimmed, how a filter extends it)."""
        return (at_cut if self.head_cut else at_end, at_cut if self.tail_cut else at_end)


#: a stretch that is a whole recording
WHOLE = Ends()


#: columns filtered in one call of :func:`lowpass` by ``_lowpass_live`` (a block of 30,000
#: samples at 250 Hz is 15 MB)
LOWPASS_BLOCK = 64


def lowpass(x: np.ndarray, sample_rate: float, cutoff_hz: float, order: int = 4,
            ends: tuple[str, str] = (ODD, ODD)) -> np.ndarray:
    """Zero-phase Butterworth low-pass of ``x`` along axis 0 (``butter`` + ``sosfiltfilt``).

    ``ends``: how ``x`` is extended past its first and its last sample (:data:`ODD`, :data:`EVEN`,
    :data:`POLYNOMIAL`); ``(ODD, ODD)`` is ``sosfiltfilt``'s own padding, bit for bit.
    """
    return _lowpass_whole(np.asarray(x, dtype=float), sample_rate, cutoff_hz, order, ends)


def _lowpass_whole(x: np.ndarray, sample_rate: float, cutoff_hz: float, order: int, ends: tuple[str, str]
                   ) -> np.ndarray:
    """:func:`lowpass` of ``x`` (N, ...) in one call of the filter."""
    from scipy import signal as sps  # here, not at the top: a second and more of every command's start
    sos = sps.butter(order, cutoff_hz, btype="low", fs=sample_rate, output="sos")
    if tuple(ends) == (ODD, ODD):
        return sps.sosfiltfilt(sos, x, axis=0)
    head = _extension(x, ends[0], sos, sample_rate, cutoff_hz, order)
    tail = _extension(x[::-1], ends[1], sos, sample_rate, cutoff_hz, order)[::-1]
    return sps.sosfiltfilt(sos, np.concatenate([head, x, tail]), axis=0, padtype=None)[len(head):len(head) + len(x)]


def _lowpass_into(x: np.ndarray, columns: np.ndarray, out: np.ndarray, kept: slice, sample_rate: float,
                  cutoff_hz: float, order: int, ends: tuple[str, str], block: int) -> None:
    """Writes the rows ``kept`` (a slice of the N) of :func:`lowpass` of the ``columns`` (indices)
    of ``x`` (N, L) into the same columns of ``out`` (len(range(N)[kept]), L), ``block`` columns
    at a time: each column's values are those of one call of the filter on all of them (the
    ends' polynomial fits, whose least squares take the columns together, are made for all at
    once), and no array of all the filtered columns at every row is made (at the Stewart's
    30,000 rows x 1,206 live columns, 290 MB written and read again for the rows kept)."""
    from scipy import signal as sps
    sos = sps.butter(order, cutoff_hz, btype="low", fs=sample_rate, output="sos")
    if tuple(ends) == (ODD, ODD):
        for k in range(0, len(columns), block):
            cols = columns[k:k + block]
            out[:, cols] = sps.sosfiltfilt(sos, x[:, cols], axis=0)[kept]
        return
    live = x[:, columns]
    head = _extension(live, ends[0], sos, sample_rate, cutoff_hz, order)
    tail = _extension(live[::-1], ends[1], sos, sample_rate, cutoff_hz, order)[::-1]
    rows = slice(len(head), len(head) + len(x))
    for k in range(0, len(columns), block):
        extended = np.concatenate([head[:, k:k + block], live[:, k:k + block], tail[:, k:k + block]])
        out[:, columns[k:k + block]] = sps.sosfiltfilt(sos, extended, axis=0, padtype=None)[rows][kept]


def _extension(x: np.ndarray, kind: str, sos: np.ndarray, sample_rate: float, cutoff_hz: float,
               order: int) -> np.ndarray:
    """The samples to put before ``x[0]`` (in time order) for a filter pass of :func:`lowpass`."""
    if kind in (ODD, EVEN):
        # sosfiltfilt's default pad length (its sections have no zeros at the origin)
        n = min(3 * (2 * len(sos) + 1), len(x) - 1)
        mirrored = x[n:0:-1]
        return 2 * x[0] - mirrored if kind == ODD else mirrored
    if kind != POLYNOMIAL:
        raise ValueError(f"unknown extension {kind!r} (one of {ODD}, {EVEN}, {POLYNOMIAL})")
    fit = min(2 * lobe_width(sample_rate, cutoff_hz, order), len(x))
    length = settling_length(sample_rate, cutoff_hz, order)
    degree = min(EXTENSION_DEGREE, fit - 1)
    k = np.arange(fit) / fit                                   # abscissa scaled to [0, 1): conditioning
    coef, *_ = np.linalg.lstsq(np.vander(k, degree + 1), x[:fit].reshape(fit, -1), rcond=None)
    before = np.vander(np.arange(-length, 0) / fit, degree + 1) @ coef
    return before.reshape((length,) + x.shape[1:])


#: fourth-order central-difference stencils (offsets -2..2) of the first and second derivative
_D1 = np.array([1.0, -8.0, 0.0, 8.0, -1.0]) / 12.0
_D2 = np.array([-1.0, 16.0, -30.0, 16.0, -1.0]) / 12.0


def central_derivatives(x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and second time derivatives of ``x`` (N, ...) sampled at times ``t`` (N,).

    On a uniform grid (the SYNC grid of a recording): fourth-order central differences inside
    (five-point stencils, truncation error ``h⁴ x⁽⁶⁾/90`` for the second derivative), the
    second-order ones of ``numpy.gradient`` on the two samples at each end. On a non-uniform
    grid: ``numpy.gradient`` twice (second order, one-sided second order at the ends).
    The second order is not enough for identification: it scales an acceleration component of
    frequency f by ``1 - (2 pi f h)^2 / 12``, a bias of the inertial parameters comparable to
    their standard deviation on a well-excited 250 Hz recording.
    """
    x = np.asarray(x, dtype=float)
    t = np.asarray(t, dtype=float)
    xd = np.gradient(x, t, axis=0, edge_order=2)
    xdd = np.gradient(xd, t, axis=0, edge_order=2)
    dt = np.diff(t)
    if len(t) < 5 or np.ptp(dt) > 1e-9 * np.mean(dt):
        return xd, xdd
    h = float(np.mean(dt))
    inner = slice(2, len(t) - 2)
    window = np.lib.stride_tricks.sliding_window_view(x, 5, axis=0)        # (N-4, ..., 5)
    xd[inner] = window @ _D1 / h
    xdd[inner] = window @ _D2 / h**2
    return xd, xdd


def parallel_decimate(settings: FilterSettings, *arrays: np.ndarray, ends: Ends = WHOLE) -> tuple[np.ndarray, ...]:
    """Filter every array with the same zero-phase low-pass, trim the edges, decimate.

    Each array has the sample index on axis 0 (e.g. torques (N, k) and regressor (N, k, n));
    all must have the same length N. ``ends``: where the stretch ends (:class:`Ends`): mirrored
    (:data:`EVEN`) past a cut and trimmed by :attr:`FilterSettings.cut_trim` there, reflected
    (:data:`ODD`) and trimmed by ``trim`` at a recording's own end. Returns the arrays of length
    ``ceil((N - head - tail) / decimation)`` (``head, tail = settings.trims(ends)``), in the
    order given.
    """
    lengths = {len(a) for a in arrays}
    if len(lengths) != 1:
        raise ValueError(f"parallel_decimate needs arrays of one length, got lengths {sorted(lengths)}")
    n = lengths.pop()
    head, tail = settings.trims(ends)
    if n <= head + tail:
        raise ValueError(f"{n} samples are too few for trimming {head} and {tail} samples at the ends")
    window = kept_samples(settings, n, ends)
    pads = ends.pick(EVEN, ODD)
    return tuple(_lowpass_live(a, settings, settings.decimation_cutoff_hz, pads, window) for a in arrays)


def through_position_lowpass(settings: FilterSettings, tau: np.ndarray, regressor: np.ndarray,
                             columns: Sequence[int], ends: Ends = WHOLE, copy: bool = True
                             ) -> tuple[np.ndarray, np.ndarray]:
    """The forces ``tau`` (N, a) and the regressor's ``columns`` (of ``regressor`` (N, a, n))
    through the positions' low-pass (:func:`prepare_actuated`: ``position_cutoff_hz``, the same
    order), before the parallel filter: returns the regressor (a copy; with ``copy`` False
    ``regressor`` itself, a float array filtered in place, where the caller has no other use
    for it) and the forces.

    The rest of the regressor is computed from the low-passed positions, so it has passed that
    filter already (the inertial and viscous terms are smooth functions of the motion, linear in
    its acceleration and rate). The forces have not, and neither has a Coulomb column: the sign
    of a low-passed rate switches as sharply as the sign of the rate. Without this, the force
    a motion has where the positions' low-pass attenuates and the parallel filter still passes
    (the links' reversals, about the band's edge) reaches the fit on the force side only: a bias
    of the inertial terms (docs/identification.md, *Where the forces and the regressor part*)."""
    pads = ends.pick(POLYNOMIAL, ODD)      # past a cut as the positions are
    tau = lowpass(tau, settings.sample_rate, settings.position_cutoff_hz, settings.order, pads)
    regressor = np.array(regressor, dtype=float, copy=copy or None)
    columns = list(columns)
    regressor[:, :, columns] = _lowpass_live(regressor[:, :, columns], settings, settings.position_cutoff_hz, pads)
    return regressor, tau


def _lowpass_live(a: np.ndarray, settings: FilterSettings, cutoff_hz: float, pads: tuple[str, str],
                  kept: slice = slice(None)) -> np.ndarray:
    """:func:`lowpass` of ``a`` (N, ...) at ``cutoff_hz`` (``settings``' rate and order), its
    samples ``kept`` (a slice of the N: :func:`kept_samples`), filtering only the columns that
    are not zero throughout (a regressor's columns are often structurally zero: another axis's
    parameters, a parameter the motion does not excite); a zero column's low-pass is zero.
    The columns are filtered in blocks of :data:`LOWPASS_BLOCK` (each column on its own, as
    in one call: the same values), so that a large regressor (the Stewart's 30,000 x 1,368
    columns) is not copied whole by each of the filter's passes."""
    flat = np.asarray(a, dtype=float).reshape(len(a), -1)
    live = np.flatnonzero(np.any(flat != 0.0, axis=0))
    if len(live) == flat.shape[1] <= LOWPASS_BLOCK:     # the filter's own array (its own strides)
        return lowpass(a, settings.sample_rate, cutoff_hz, settings.order, pads)[kept]
    # the kept rows of an array of every row, as before the blocks: the same strides, so that the
    # sums taken of it later add in the same order (its other rows are never written: zeros
    # the system has not even mapped)
    out = np.zeros(flat.shape)
    if len(live):
        _lowpass_into(flat, live, out[kept], kept, settings.sample_rate, cutoff_hz, settings.order, pads,
                      LOWPASS_BLOCK)
    return out.reshape(np.shape(a))[kept]


@functools.lru_cache(maxsize=None)
def lobe_width(sample_rate: float, cutoff_hz: float, order: int = 4) -> int:
    """Half-width (samples at ``sample_rate``) of the main lobe of the impulse response of the
    zero-phase Butterworth low-pass (:func:`lowpass`): the samples to its first zero crossing.
    A filtered sample is a weighted mean of the input over about this many samples on each side
    (about half a period of the cut-off)."""
    n = 4 * math.ceil(sample_rate / cutoff_hz) + 1
    impulse = np.zeros(2 * n + 1)
    impulse[n] = 1.0
    response = lowpass(impulse, sample_rate, cutoff_hz, order)[n:]
    return int(np.argmax(response <= 0.0))


def settling_length(sample_rate: float, cutoff_hz: float, order: int = 4) -> int:
    """Samples (at ``sample_rate``) over which the transient of the Butterworth low-pass decays by
    1e-9: the slowest pole's decay, ``exp(-2 pi cutoff sin(pi / (2 order)) t)`` (216 samples at
    250 Hz, 10 Hz, order 4). A pass of :func:`lowpass` starts at rest on the first sample of the
    extended stretch; past an extension this long its start is gone before the data begins."""
    return math.ceil(math.log(1e9) / (2.0 * math.pi * cutoff_hz * math.sin(math.pi / (2 * order))) * sample_rate)


def main_lobe(settings: FilterSettings) -> int:
    """Half-width (samples at the input rate) of the main lobe of the parallel filter's impulse
    response (:func:`parallel_decimate`, :func:`lobe_width`)."""
    return lobe_width(settings.sample_rate, settings.decimation_cutoff_hz, settings.order)


def _window_count(mask: np.ndarray, before: int, after: int) -> np.ndarray:
    """(N, ...) int: how many True of ``mask`` (N, ...) lie in samples ``i - before .. i + after``
    along axis 0 (the window clipped at the ends)."""
    n = len(mask)
    count = np.concatenate([np.zeros((1,) + mask.shape[1:], np.int64), np.cumsum(mask, axis=0)])
    index = np.arange(n)
    return count[np.minimum(index + after + 1, n)] - count[np.maximum(index - before, 0)]


def runs_at_least(mask: np.ndarray, length: int) -> np.ndarray:
    """``mask`` (N, ...) bool keeping only its runs of at least ``length`` consecutive True along axis 0."""
    if length <= 1:
        return mask.copy()
    starts = _window_count(mask, 0, length - 1) == length     # the ``length`` samples from here all True
    return _window_count(starts, length - 1, 0) > 0


def near(mask: np.ndarray, width: int) -> np.ndarray:
    """``mask`` (N, ...) bool widened by ``width`` samples on each side along axis 0: True
    where a True of ``mask`` lies within ``width`` samples."""
    return _window_count(mask, max(width, 0), max(width, 0)) > 0


def near_rest(slow: np.ndarray, settings: FilterSettings) -> np.ndarray:
    """(N, a) bool: the samples the fits leave out of an axis's rows, given ``slow`` (N, a): the
    axis slower than its threshold (``identification.min_speed``) at the input rate.

    A slow sample itself, and every sample within the parallel filter's main lobe
    (:func:`main_lobe`) of a *stop*: a slow stretch at least half that lobe long, where the
    axis lingers near zero speed (the corners of a rest-to-rest path). There Coulomb friction
    switches at an ill-defined time (the drive may overshoot zero speed while the filtered
    encoder does not), and the parallel filter would spread the mismatch over its window. A
    shorter slow stretch is a clean reversal through zero speed: its sign switch is sharp and
    the rows around it, with the largest accelerations, are kept.
    """
    lobe = main_lobe(settings)
    return slow | near(runs_at_least(slow, lobe // 2), lobe)


def running_average(x: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """What the drives' running average of their current makes of ``x`` (N, a, ...), sampled
    on a uniform SYNC grid: along axis 0, the part of axis ``j`` (axis 1) filtered by
    ``y[k+1] = A y[k] + B0 x[k] + B1 x[k+1]``, ``steps[j] = (A, B0, B1)`` (the
    :meth:`drivers.profiles.AveragingFilter.over_period` of the grid's period), from rest on
    ``x[0]`` (``y[0] = x[0]``).

    The filter is linear and time-invariant, and so is ``tau = Y pi`` in its parameters: forces
    from averaged currents are the averaged forces of the model, ``avg(tau) = avg(Y) pi``, so the
    regressor filtered by this matches them exactly once the start (a few filter time
    constants, inside the preparation's trim) has passed.
    """
    x = np.asarray(x, dtype=float)
    steps = np.asarray(steps, dtype=float)
    if x.ndim < 2 or steps.shape != (x.shape[1], 3):
        raise ValueError(f"expected x (N, a, ...) and steps (a, 3), got {x.shape} and {steps.shape}")
    from scipy import signal as sps  # here, not at the top (see lowpass)
    out = np.empty_like(x)
    for j, (pole, b0, b1) in enumerate(steps):
        b, a = [b1, b0], [1.0, -pole]
        start = sps.lfilter_zi(b, a)[0] * x[:1, j]        # the filter at rest on the first sample
        out[:, j], _ = sps.lfilter(b, a, x[:, j], axis=0, zi=start)
    return out


def kept_samples(settings: FilterSettings, n: int, ends: Ends = WHOLE) -> slice:
    """The samples (of n) that :func:`parallel_decimate` keeps: edges trimmed (per ``ends``,
    :meth:`FilterSettings.trims`), decimated."""
    head, tail = settings.trims(ends)
    return slice(head, n - tail, settings.decimation)


@dataclass(frozen=True)
class ActuatedSamples:
    """Actuated motion and forces at the input rate, SI units.

    Attributes:
        t: sample times (N,), s.
        Theta, Thetad, Thetadd: filtered positions and their central derivatives (N, 6):
            rad, rad/s, rad/s² for the revolute axes and m, m/s, m/s² for the carriages.
        tau: joint forces (N, 6) from the currents: N·m (revolute) and N (prismatic).
    """

    t: np.ndarray
    Theta: np.ndarray
    Thetad: np.ndarray
    Thetadd: np.ndarray
    tau: np.ndarray


def prepare_actuated(
    t: np.ndarray,
    Theta: np.ndarray,
    current: np.ndarray,
    force_per_amp: np.ndarray,
    settings: FilterSettings | None = None,
    ends: Ends = WHOLE,
) -> ActuatedSamples:
    """Measured positions and currents → filtered positions, rates, accelerations and forces.

    Args:
        t: sample times (N,), s, strictly increasing and (nearly) uniform.
        Theta: measured actuated positions (N, m) in rad / m.
        current: motor currents (N, m), A.
        force_per_amp: (m,) N·m/A or N/A per axis (``drivers.units.AxisScaling.force_per_amp``).
        settings: filter settings; default ``FilterSettings.for_sample_rate`` of the data.
        ends: where the stretch ends (:class:`Ends`): past a cut the positions are extended by
            their least-squares polynomial (:data:`POLYNOMIAL`), at a recording's own end
            reflected (:data:`ODD`).

    The forces are *not* filtered here: they get the parallel filter together with the
    regressor (:func:`parallel_decimate`).
    """
    t = np.asarray(t, dtype=float)
    Theta = np.asarray(Theta, dtype=float)
    current = np.asarray(current, dtype=float)
    force_per_amp = np.asarray(force_per_amp, dtype=float)
    if t.ndim != 1 or Theta.shape[0] != t.size or current.shape != Theta.shape:
        raise ValueError(
            f"expected t (N,), Theta (N, m), current (N, m); got {t.shape}, {Theta.shape}, {current.shape}"
        )
    if force_per_amp.shape != Theta.shape[1:]:
        raise ValueError(f"force_per_amp must have shape {Theta.shape[1:]}, got {force_per_amp.shape}")
    dt = np.diff(t)
    if np.any(dt <= 0):
        raise ValueError(f"sample times must be strictly increasing (first bad index {int(np.argmax(dt <= 0)) + 1})")
    if settings is None:
        settings = FilterSettings.for_sample_rate(1.0 / float(np.median(dt)))
    filtered = lowpass(Theta, settings.sample_rate, settings.position_cutoff_hz, settings.order,
                       ends.pick(POLYNOMIAL, ODD))
    Thetad, Thetadd = central_derivatives(filtered, t)
    return ActuatedSamples(t=t, Theta=filtered, Thetad=Thetad, Thetadd=Thetadd, tau=current * force_per_amp)
