"""Data preparation for the fits: derivatives, rows left out near rest, per-trajectory filter bandwidth."""

import dataclasses
import numpy as np
import pytest
from scipy import linalg
from scipy import signal as sps

from drivers.recording import Recording
from drivers.recording_metadata import RecordingMetadata
from drivers.sim.plant import DEFAULT_MAX_SUBSTEP
from ident_hw.config import ConfigError, load_config, to_model
from ident_hw.experiment.inputs import identification_plan, trajectory_inputs
from ident_hw.experiment.offline import identify
from ident_hw.experiment.preparation import prepare
from ident_hw.segments import split, uniform
from ident_hw.experiment.plan import plan
from ident_hw.config.robots import model_of
from ident_hw.experiment.robot_trajectories import excitation_of
from ident_hw.identification.least_squares import ols, output_noise_std, wls
from ident_hw.filtering import (EVEN, ODD, POLYNOMIAL, Ends, FilterSettings, central_derivatives, lowpass, main_lobe,
                             near, near_rest, runs_at_least)

from ident_scenarios import CONFIGS, NAMES, exact_recording, without_draws
from ident_hw.config.to_drivers import axis_scaling
from ident_hw.config.to_identification import filter_settings




def _inputs(config, name):
    """The identification's inputs of trajectory ``name`` (the filter's own band for a name the
    config does not list)."""
    if any(t.name == name for t in config.trajectories):
        return trajectory_inputs(config.trajectory(name), config.identification)
    return identification_plan(config).inputs_of(name)


def motion_bandwidth(config, name):
    return _inputs(config, name).bandwidth


def position_margin(config, name):
    return _inputs(config, name).position_margin

def test_central_derivatives_are_fourth_order_on_a_uniform_grid():
    """Against the analytic derivatives of a sine: the interior error falls 16x when h halves."""
    w = 2 * np.pi * 3.0
    errors = []
    for h in (0.004, 0.002):
        t = np.arange(0.0, 1.0, h)
        x = np.column_stack([np.sin(w * t), 2 * np.cos(w * t)])
        xd, xdd = central_derivatives(x, t)
        inner = slice(2, -2)
        errors.append((np.abs(xd[inner] - w * np.column_stack([np.cos(w * t), -2 * np.sin(w * t)])[inner]).max(),
                       np.abs(xdd[inner] + w**2 * x[inner]).max()))
    (v1, a1), (v2, a2) = errors
    assert v1 / v2 == pytest.approx(16.0, rel=0.05) and a1 / a2 == pytest.approx(16.0, rel=0.05)
    assert a1 < 1e-3 * w**2                              # second order would leave (w h)^2/12 = 0.05 %


def test_central_derivatives_on_a_non_uniform_grid_fall_back_to_second_order():
    t = np.cumsum(np.r_[0.0, np.full(50, 0.01), np.full(50, 0.02)])
    x = (t**2)[:, None]                                  # exact for second-order differences
    xd, xdd = central_derivatives(x, t)
    np.testing.assert_allclose(xd[:, 0], 2 * t, atol=1e-9)
    np.testing.assert_allclose(xdd[:, 0], 2.0, atol=1e-6)


def _problem(seed=0, n=400, k=3, p=4):
    rng = np.random.default_rng(seed)
    Y = rng.normal(size=(n, k, p))
    truth = rng.normal(size=p)
    tau = Y @ truth + rng.normal(0.0, [0.1, 0.2, 0.4][:k], size=(n, k))
    return Y, tau


def test_nan_rows_are_left_out_of_ols_and_its_statistics():
    """NaN outputs leave their rows out: the estimate, sigma² and dof equal those of least squares
    on the remaining rows, stacked by hand (white-residual covariance, lags=0)."""
    Y, tau = _problem()
    rng = np.random.default_rng(1)
    out = rng.random(tau.shape) < 0.3
    masked = np.where(out, np.nan, tau)
    fit = ols(Y, masked, list("abcd"), lags=0)
    keep = ~out
    W = Y[keep]                                          # (rows, p): only the rows kept
    y = tau[keep]
    coef, *_ = linalg.lstsq(W, y)
    r = len(y)
    sigma2 = np.sum((y - W @ coef) ** 2) / (r - W.shape[1])
    np.testing.assert_allclose(fit.coef, coef, rtol=1e-10)
    assert fit.sigma2 == pytest.approx(sigma2, rel=1e-10)
    np.testing.assert_allclose(fit.covariance, sigma2 * np.linalg.inv(W.T @ W), rtol=1e-8)
    rms = [np.sqrt(np.mean((y - W @ coef)[np.nonzero(keep)[1] == j] ** 2)) for j in range(3)]
    np.testing.assert_allclose(fit.residual_rms, rms, rtol=1e-10)


def test_an_output_without_rows_weighs_nothing():
    """The sweep leaves every link row out (links at rest): WLS still fits on the other outputs."""
    Y, tau = _problem(seed=2)
    masked = tau.copy()
    masked[:, 0] = np.nan
    sigma = output_noise_std(Y, masked)
    assert sigma[0] == 1.0 and np.all(sigma[1:] > 0)
    fit = wls(Y, masked, list("abcd"))
    alone = wls(Y[:, 1:, :], tau[:, 1:], list("abcd"))
    np.testing.assert_allclose(fit.coef, alone.coef, rtol=1e-8)


def test_filter_bandwidth_per_trajectory():
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    excitation = next(t for t in config.trajectories if t.kind == "fourier")
    ex = excitation_of(excitation)
    assert motion_bandwidth(config, excitation.name) == pytest.approx(ex.a.shape[1] * ex.base_frequency)
    assert motion_bandwidth(config, "square1") == config.identification.filter.bandwidth
    assert motion_bandwidth(config, "not-in-the-config") == config.identification.filter.bandwidth


def test_filter_bandwidth_key_overrides(tmp_path):
    path = tmp_path / "sim.yaml"
    path.write_text((CONFIGS / "sim-3prrr.yaml").read_text()
                    .replace("extends: robot-3prrr.yaml", f"extends: {CONFIGS / 'robot-3prrr.yaml'}")
                    .replace("{name: square1, kind: square,", "{name: square1, kind: square, bandwidth: 2.5,"))
    config = load_config(path)
    assert motion_bandwidth(config, "square1") == 2.5
    assert filter_settings(config.identification.filter, 250.0, 2.5).cutoff_hz == pytest.approx(25.0)


def test_main_lobe_of_the_parallel_filter_against_its_frequency_response():
    """The zero-phase filter's impulse response is the inverse DFT of |H|^2 (the filter run forward
    and backward): its first non-positive sample is the main lobe's half-width, about half a
    period of the cut-off for the Butterworth."""
    for rate, bandwidth, order in ((250.0, 1.0, 4), (250.0, 1.5, 4), (1000.0, 5.0, 4), (250.0, 1.5, 2)):
        settings = FilterSettings.for_sample_rate(rate, bandwidth, order)
        sos = sps.butter(order, settings.decimation_cutoff_hz, fs=rate, output="sos")
        n = 1 << 14
        _, h = sps.sosfreqz(sos, worN=np.linspace(0.0, np.pi, n // 2 + 1))
        response = np.fft.irfft(np.abs(h) ** 2, n)
        expected = int(np.argmax(response <= 0.0))
        assert main_lobe(settings) == expected, (rate, bandwidth, order)
        assert 0.35 < expected * settings.decimation_cutoff_hz / rate < 0.75


def test_a_cut_costs_the_main_lobe_a_recording_end_the_full_trim():
    """The support at a cut is the main lobe of the wider filter (13 rows at 250 Hz and 10 Hz:
    the excitation's; 9 at 15 Hz), at the recording's own ends the three periods of the cut-off;
    ``split`` takes each at its ends and says which end is which. Hand-made: 100 rows, row 40
    without data, trim 6, cut_trim 2."""
    settings = FilterSettings.for_sample_rate(250.0, 1.0)
    assert (settings.trim, settings.cut_trim) == (75, 13) == (75, main_lobe(settings))
    assert FilterSettings.for_sample_rate(250.0, 1.5).cut_trim == 9
    assert settings.trims(Ends(head_cut=True)) == (13, 75) and settings.trims(Ends()) == (75, 75)
    n = 100
    valid = np.ones((n, 2), bool)
    valid[40, 0] = False
    seg = split(np.arange(n) * 0.01, 0.01, valid, np.zeros((n, 2)), np.zeros((n, 2)), current_limit=np.ones(2),
                acceleration_limit=np.ones(2), counts_per_unit=np.ones(2), trim=6, min_kept=1, cut_trim=2)
    assert [(s.rows.start, s.rows.stop, s.ends) for s in seg.stretches] == [
        (0, 40, Ends(head_cut=False, tail_cut=True)), (41, 100, Ends(head_cut=True, tail_cut=False))]
    assert seg.left_out["edges"] == (6 + 2) + (2 + 6) and seg.left_out["incomplete"] == 1
    # a stretch keeps at least min_kept rows beyond its two ends' support: 40 - 8 = 32 kept
    short = split(np.arange(n) * 0.01, 0.01, valid, np.zeros((n, 2)), np.zeros((n, 2)), current_limit=np.ones(2),
                  acceleration_limit=np.ones(2), counts_per_unit=np.ones(2), trim=6, min_kept=33, cut_trim=2)
    assert [s.rows.start for s in short.stretches] == [41] and short.left_out["short"] == 40


def test_a_stretch_is_continued_past_a_cut_by_its_own_polynomial():
    """Past a cut the positions are extended by their least-squares quartic and the parallel
    filter mirrors the rows: a quartic motion comes through the position filter unchanged to the
    last row (the odd reflection flips its acceleration: off by a fifth of it next to the end), and
    white noise next to a cut is averaged (the odd reflection hands the end row's noise through).
    At a recording's own end the filter is ``sosfiltfilt``'s, bit for bit."""
    rate, cutoff = 250.0, 10.0
    t = np.arange(300) / rate
    x = 0.3 * t**4 - t**3 + 2 * t**2 + t            # rad
    acc = 3.6 * t**2 - 6 * t + 4
    smooth = lowpass(x, rate, cutoff, 4, (POLYNOMIAL, POLYNOMIAL))
    np.testing.assert_allclose(smooth, x, rtol=0, atol=1e-9)
    _, edge = central_derivatives(lowpass(x, rate, cutoff), t)
    assert abs(edge[5] - acc[5]) > 0.2 * abs(acc[5])
    noise = np.random.default_rng(0).standard_normal((300, 4000))
    sd = {pad: lowpass(noise, rate, cutoff, 4, (pad, pad)).std(axis=1) for pad in (ODD, EVEN)}
    assert sd[ODD][0] > 3 * sd[ODD][150] and sd[EVEN][0] < 1.5 * sd[EVEN][150]
    sos = sps.butter(4, cutoff, fs=rate, output="sos")
    assert np.array_equal(lowpass(noise[:, :3], rate, cutoff), sps.sosfiltfilt(sos, noise[:, :3], axis=0))
    head = lowpass(noise[:, :3], rate, cutoff, 4, (EVEN, ODD))
    np.testing.assert_allclose(head[-40:], lowpass(noise[:, :3], rate, cutoff)[-40:], rtol=0, atol=1e-9)


def test_near_widens_a_mask_like_a_brute_force_loop():
    rng = np.random.default_rng(3)
    mask = rng.random((200, 3)) < 0.03
    for width in (0, 1, 9):
        expected = np.array([[mask[max(0, i - width):i + width + 1, j].any() for j in range(3)] for i in range(200)])
        np.testing.assert_array_equal(near(mask, width), expected)


def test_runs_at_least_keeps_the_long_runs_like_a_brute_force_loop():
    rng = np.random.default_rng(5)
    mask = rng.random((300, 2)) < 0.6
    for length in (1, 2, 4, 7):
        expected = np.zeros_like(mask)
        for j in range(2):
            i = 0
            while i < 300:
                if mask[i, j]:
                    end = i
                    while end < 300 and mask[end, j]:
                        end += 1
                    expected[i:end, j] = end - i >= length
                    i = end
                else:
                    i += 1
        np.testing.assert_array_equal(runs_at_least(mask, length), expected)
    assert not runs_at_least(np.ones((3, 1), bool), 5).any()      # a stretch shorter than the run asked for


def test_a_stop_is_widened_by_the_filter_lobe_a_clean_reversal_is_not():
    """250 Hz, 15 Hz cut-off: a velocity through zero at 20 rad/s² is below 0.05 rad/s for a sample
    or two (a reversal: only those are left out); a rest-to-rest corner lingers (v ~ t^2) and every
    sample within the main lobe around it is left out too."""
    settings = FilterSettings.for_sample_rate(250.0, 1.5)
    lobe = main_lobe(settings)
    t = np.arange(-0.5, 0.5, 1 / 250.0)
    reversal = np.abs(20.0 * t)[:, None] < 0.05
    stop = np.abs(40.0 * t**2)[:, None] < 0.05
    assert 1 <= reversal.sum() < lobe // 2 <= stop.sum()
    np.testing.assert_array_equal(near_rest(reversal, settings), reversal)
    slow = np.flatnonzero(stop[:, 0])
    expected = (np.arange(len(t)) >= slow[0] - lobe) & (np.arange(len(t)) <= slow[-1] + lobe)
    np.testing.assert_array_equal(near_rest(stop, settings)[:, 0], expected)


def test_rows_of_axes_near_rest_are_left_out_of_the_fits():
    """The carriage sweep (links held): every link row is left out, a carriage row only where the
    carriage moves at >= min_speed x its velocity limit throughout the parallel filter's main lobe
    around it (the sweep's slow stretches are all stops: rest-to-rest moves); plots and metrics
    keep every row."""
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    robot = model_of(config.robot)
    (planned,) = plan(config, ["sweep"])
    tr = planned.trajectory
    fpa = np.array([axis_scaling(a).force_per_amp for a in config.robot.actuators])
    tau = robot.inverse_dynamics(tr.X, tr.Xd, tr.Xdd, tr.zeta, tr.zetad, tr.zetadd, to_model.inertial_params(config.sim.truth))
    n = len(tr.t)
    period = float(tr.t[1] - tr.t[0])
    rec = Recording(t=tr.t, cycle=np.arange(n), position=tr.Theta, velocity=tr.Thetad, current=tau / fpa,
                    statusword=np.zeros((n, 6), np.int32), target=tr.Theta, valid=np.ones((n, 6), bool),
                    metadata=RecordingMetadata(trajectory="sweep", sync_period=period))
    p = prepare(identification_plan(config), robot, "sweep", rec)
    assert not p.moving[:, :3].any()
    threshold = config.identification.min_speed * np.array([a.limits.velocity for a in config.robot.actuators[3:]])
    lobe = main_lobe(filter_settings(config.identification.filter, 1.0 / period, motion_bandwidth(config, "sweep")))
    t = tr.t - tr.t[0]
    slowest = np.array([np.abs(tr.Thetad[np.abs(t - tk) <= (lobe + 0.5) * period, 3:]).min(axis=0) for tk in p.t])
    clear = np.abs(slowest - threshold) > 1e-4   # away from the threshold
    np.testing.assert_array_equal(p.moving[:, 3:][clear], (slowest >= threshold)[clear])
    assert 0.2 < p.moving[:, 3:].mean() < 1.0
    assert np.isnan(p.tau_fit[~p.moving]).all() and np.isfinite(p.tau).all()


def test_check_notes_set_point_quantisation_above_the_motion(tmp_path):
    """One count per SYNC period on a link: 2048 counts x 26 per turn at 250 Hz (the paper's rate,
    the shipped simulation's) is 7.37 rad/s², above the excitation's RMS link accelerations
    (1.5-2.3), below the squares' (8-10); at 100 Hz it is 1.18 rad/s², below both: no note. Said
    only without the encoder draws (identification.encoder_draws 0): with them, as shipped, every
    sigma and the verdict's noise floor hold the encoders' resolution, and nothing is noted."""
    shipped = load_config(CONFIGS / "sim-3prrr.yaml")
    assert shipped.bus.sync_rate == 250.0 and shipped.identification.encoder_draws > 0
    assert all(p.notes == () for p in plan(shipped))
    without = without_draws(shipped)
    quantum = 250.0**2 / (2048 * 26 / (2 * np.pi))
    assert quantum == pytest.approx(7.37, abs=0.01)
    planned = {p.config.name: p for p in plan(without, ["square1", "excitation"])}
    assert planned["square1"].ok and planned["square1"].notes == ()
    (note,) = planned["excitation"].notes
    assert all(f"theta{i} {quantum:.3g} rad/s²" in note for i in (1, 2, 3)) and "zeta" not in note
    assert planned["excitation"].ok and "note: " in planned["excitation"].describe()
    path = tmp_path / "sim-100.yaml"
    path.write_text(f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n"
                    "bus: {interface: virtual, channel: unused, sync_rate: 100.0}\n")
    assert all(p.notes == () for p in plan(without_draws(load_config(path)), ["square1", "excitation"]))


def test_gaps_and_rows_left_out_cut_the_recording_and_are_counted():
    """Hand-made, 10 ms period, 60 rows: slots 20-22 skipped (a gap), row 30 incomplete, row 40's
    current at the limit, a set-point jump at row 50; trim 2, at least 6 rows per stretch."""
    n, period = 60, 0.01
    slots = np.r_[np.arange(20), np.arange(23, 63)]
    t = slots * period + 1.7e9
    valid = np.ones((n, 2), bool)
    valid[30, 1] = False
    current = np.zeros((n, 2))
    current[40, 0] = -0.99
    target = np.zeros((n, 2))
    target[50:, 1] = 1.0                                 # a step: second difference 1 m/count at 49 and 50
    seg = split(t, period, valid, current, target, current_limit=np.array([1.0, 1.0]),
                acceleration_limit=np.array([10.0, 10.0]), counts_per_unit=np.array([1000.0, 1000.0]),
                trim=2, min_kept=2)
    assert seg.gaps == 1 and seg.skipped_slots == 3
    np.testing.assert_allclose(seg.t, slots * period, atol=1e-6)
    assert [(s.start, s.stop) for s in seg.slices] == [(0, 20), (20, 30), (31, 40), (41, 49), (51, 60)]
    assert seg.left_out == {"incomplete": 1, "saturated": 1, "late_setpoint": 2, "edges": 5 * 4, "short": 0}
    short = split(t, period, valid, current, target, current_limit=np.array([1.0, 1.0]),
                  acceleration_limit=np.array([10.0, 10.0]), counts_per_unit=np.array([1000.0, 1000.0]),
                  trim=2, min_kept=6)
    assert [(s.start, s.stop) for s in short.slices] == [(0, 20), (20, 30)]
    assert short.left_out["short"] == 9 + 8 + 9 and short.left_out["edges"] == 8
    assert "1 gap (3 SYNC slots skipped)" in seg.describe() and "1 incomplete" in seg.describe()


def test_a_jittered_stretch_is_put_on_a_uniform_grid_by_its_own_time_stamps():
    """Rows stamped at a jittered SYNC (up to 0.3 period): the stretch interpolated onto its
    uniform grid equals the motion there (cubic spline: 1e-7 of a 2 Hz sine at 250 Hz)."""
    rng = np.random.default_rng(3)
    period = 0.004
    t = np.arange(500) * period + rng.uniform(-0.3, 0.3, 500) * period
    t[0], t[-1] = 0.0, 499 * period
    w = 2 * np.pi * 2.0
    grid, x, i = uniform(t, np.column_stack([np.sin(w * t)]), np.column_stack([np.cos(w * t)]))
    np.testing.assert_allclose(grid, np.arange(500) * period, atol=1e-12)
    assert np.abs(x[:, 0] - np.sin(w * grid)).max() < 1e-6
    assert np.abs(i[:, 0] - np.cos(w * grid)).max() < 1e-3       # linear: (w h)^2 / 8 of the amplitude
    exact = np.arange(10) * period
    assert uniform(exact, exact[:, None])[1] is not None and uniform(exact, exact[:, None])[0] is exact


def test_skipped_sync_slots_on_hardware_keep_the_fit(tmp_path):
    """Exact samples of the plant following the excitation at 100 Hz, as a thread-timed SYNC producer
    on hardware records them when it skips 40 slots in 20 s: the drives move on through each skipped
    slot, the recording has one row less each time. Cut at each gap, the base parameters stay near
    those of the complete recording; the same rows taken as consecutive periods (time stamps
    ignored) are far off. Measured: 0.30 %, 0.50 % (77 % of the rows used) and 71 % worst error."""
    names = ", ".join(NAMES)
    base = f"""trajectories:
  - {{name: excitation, kind: fourier, cycles: 4}}
identification:
  steps:
    - {{name: base, trajectories: [excitation], method: wls, parameters: [{names}]}}
  validation: []
  encoder_draws: 0        # exact positions: no encoder rounding to read again or to correct for
"""
    path = tmp_path / "hardware.yaml"
    path.write_text(f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n"
                    f"bus: {{interface: socketcan, channel: can0, sync_rate: 100.0}}\n{base}")
    config = load_config(path)
    (planned,) = plan(config, ["excitation"])
    complete = exact_recording(config, planned.trajectory, DEFAULT_MAX_SUBSTEP)
    n = len(complete.t)
    kept = np.setdiff1d(np.arange(n), np.random.default_rng(1).choice(np.arange(50, n - 50), 40, replace=False))
    skipping = Recording(t=complete.t[kept], cycle=np.arange(len(kept)), position=complete.position[kept],
                         velocity=complete.velocity[kept], current=complete.current[kept],
                         statusword=complete.statusword[kept], target=complete.target[kept],
                         valid=complete.valid[kept], metadata=complete.metadata)

    def worst_error(config, rec):
        fit = identify(config, {"excitation": rec}).base_fit
        return np.abs((fit.coef - fit.truth) / fit.truth).max()

    consecutive = Recording(**{**skipping.__dict__, "t": np.arange(len(kept)) * complete.t[1]})
    reference = worst_error(config, complete)
    cut = worst_error(config, skipping)
    as_consecutive = worst_error(config, consecutive)
    assert reference < 0.01 and cut < 2 * reference + 0.005 and as_consecutive > 0.2, \
        (reference, cut, as_consecutive)


def test_the_positions_low_pass_of_a_rest_to_rest_path_is_flat_over_the_parallel_filters_band():
    """Where a motion has force near the band edge (the paper's rest-to-rest paths), the
    positions' low-pass is close to unity over the band the parallel filter passes: the regressor
    passes it with the positions, the forces by ``through_position_lowpass``, and the two differ
    where the regressor is not linear in the motion. Twice the parallel filter's cut-off where a
    quarter of the sample rate allows it; where it does not (50 Hz), at least the band's own
    cut-off. A band-limited motion (the Fourier excitation) keeps one cut-off: a wider low-pass
    only lets in more of the encoder's rounding."""
    for rate, bandwidth in ((100.0, 1.5), (100.0, 1.0), (250.0, 1.5), (250.0, 1.0), (1000.0, 5.0)):
        settings = dataclasses.replace(FilterSettings.for_sample_rate(rate, bandwidth), position_margin=2.0)
        band = settings.decimation_cutoff_hz
        assert settings.position_cutoff_hz == pytest.approx(min(2.0 * band, 0.25 * rate)), (rate, bandwidth)
        sos = sps.butter(settings.order, settings.position_cutoff_hz, fs=rate, output="sos")
        _, h = sps.sosfreqz(sos, worN=[band], fs=rate)
        assert np.abs(h[0]) ** 2 > (0.99 if 2.0 * band <= 0.25 * rate else 0.9), (rate, bandwidth)
        one = FilterSettings.for_sample_rate(rate, bandwidth)
        assert one.position_cutoff_hz == one.cutoff_hz
    margin = dataclasses.replace(FilterSettings.for_sample_rate(50.0, 1.5), position_margin=2.0)
    assert margin.position_cutoff_hz == pytest.approx(12.5)     # fs/4: no room
    config = load_config(CONFIGS / "sim-3prrr.yaml")
    kinds = {t.name: t.kind for t in config.trajectories}
    for name, kind in kinds.items():
        expected = 2.0 if kind in ("carriage_sweep", "square", "triangle") else 1.0
        assert position_margin(config, name) == expected, (name, kind)
    assert {kinds[n] for n in kinds if position_margin(config, n) == 1.0} == {"fourier", "standstill"}
    with pytest.raises(ValueError, match="position_margin"):
        FilterSettings(100.0, 15.0, position_margin=0.5)


def test_a_configs_position_margin_sets_every_trajectorys_positions_low_pass(tmp_path):
    """``identification.filter.position_margin`` (the Delta's configs) overrides the margin of every
    trajectory, rest-to-rest or not; the positions' low-pass then cuts off that many times above
    the parallel filter, at most at a quarter of the sample rate; below 1 the config is refused,
    naming the key."""
    path = tmp_path / "wide.yaml"
    path.write_text(f"extends: {CONFIGS / 'sim-3prrr.yaml'}\nidentification: {{filter: {{position_margin: 3}}}}\n")
    config = load_config(path)
    assert {position_margin(config, t.name) for t in config.trajectories} == {3.0}
    rate = config.bus.sync_rate
    for t in config.trajectories:
        settings = filter_settings(config.identification.filter, rate, motion_bandwidth(config, t.name),
                                   position_margin(config, t.name))
        assert settings.position_cutoff_hz == pytest.approx(min(3.0 * settings.decimation_cutoff_hz, rate / 4))
    path.write_text(f"extends: {CONFIGS / 'sim-3prrr.yaml'}\nidentification: {{filter: {{position_margin: 0.5}}}}\n")
    with pytest.raises(ConfigError, match="identification.filter.position_margin"):
        load_config(path)
    delta = load_config(CONFIGS / "sim-delta.yaml")
    training = filter_settings(delta.identification.filter, delta.bus.sync_rate, motion_bandwidth(delta, "training"),
                               position_margin(delta, "training"))
    assert training.position_cutoff_hz == pytest.approx(delta.bus.sync_rate / 4)
