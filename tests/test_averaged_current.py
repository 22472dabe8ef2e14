"""The drives' averaged current (EPOS4 ``0x30D1:01``, EPOS2 ``0x2027``): the emulated one against
maxon's definition computed by hand (a first-order digital low-pass of 50 Hz cut-off at the
current loop's rate, read by a real canopen master over the virtual bus), the ``bus.current``
key that streams it, and an identification on it with the regressor through the same filter.

The hand computations run the filter sample by sample at the loop rate (25 kHz on the EPOS4,
10 kHz on the EPOS2) or use its closed-form response; none calls
:meth:`drivers.profiles.AveragingFilter.over_period`, the closed form the code uses per SYNC."""

from __future__ import annotations

import itertools
import json
import math
import os
import threading
import time
from pathlib import Path

import canopen
import dataclasses

import numpy as np
import pytest

from drivers.acquisition import master_layouts
from drivers.axis import AxisConfig
from drivers.errors import ConfigError as DriverConfigError
from drivers.profiles import EPOS4, make_object_dictionary
from drivers.recording import Recording
import nominal
from drivers.sim.drive import EmulatedDrive
from ident_hw.config import ConfigError, load_config
from ident_hw.experiment.plan import PlanInputs
from ident_hw.filtering import running_average
from ident_hw.config.robots import model_of, true_parameters
from cli_runs import ident_hw
from drivers.bus import NOTIFIER_CYCLE

ROOT = Path(__file__).resolve().parent.parent
SIM = ROOT / "configs" / "sim-3prrr.yaml"
_channels = itertools.count()

#: per generation: (averaged object, instantaneous object, current loop rate Hz)
GENERATIONS = {"epos4": ((0x30D1, 1), (0x30D1, 2), 25_000.0), "epos2": ((0x2027, 0), (0x6078, 0), 10_000.0)}
CUTOFF = 50.0    # Hz, maxon's firmware specifications
TAU = 1.0 / (2.0 * math.pi * CUTOFF)


@pytest.fixture
def drive_on_bus():
    """``make(profile)``: an emulated drive and a canopen master's view of it on a fresh virtual bus."""
    opened = []

    def make(profile):
        channel = f"averaged-test-{os.getpid()}-{next(_channels)}"
        bus_side, master = canopen.Network(), canopen.Network()
        bus_side.NOTIFIER_CYCLE = master.NOTIFIER_CYCLE = NOTIFIER_CYCLE    # a quick disconnect
        bus_side.connect(interface="virtual", channel=channel, ignore_config=True, receive_own_messages=False)
        master.connect(interface="virtual", channel=channel, ignore_config=True)
        opened.extend([bus_side, master])
        drive = EmulatedDrive(3, profile, nominal.PRISMATIC, bus_side, threading.RLock(), lambda: 0.0)
        node = master.add_node(canopen.RemoteNode(3, make_object_dictionary(profile, 3)))
        return drive, node

    yield make
    for network in opened:
        network.disconnect()


def _wait(predicate, timeout=2.0) -> bool:
    end = time.monotonic() + timeout
    while not predicate() and time.monotonic() < end:
        time.sleep(0.005)
    return predicate()


def _read(node, key) -> int:
    """An object of the drive, uploaded by SDO."""
    index, subindex = key
    return node.sdo[index].raw if subindex == 0 else node.sdo[index][subindex].raw


@pytest.mark.parametrize("profile", ["epos4", "epos2"])
def test_the_averaged_current_of_a_ramp_is_the_first_order_filters(drive_on_bus, profile):
    """At rest, then a current ramp of 100 A/s at a 250 Hz SYNC. The rig hands the drive one sample
    per period; a ramp is linear between them, so the drive's filter sees exactly the ramp. By
    hand: ``y[n] = a y[n-1] + (1 - a) x[n]`` with ``x[n] = r n / rate`` from rest gives
    ``y[n] = r / rate (n - a (1 - a^n) / (1 - a))``: behind the ramp by about the time constant
    (3.2 ms) once it settles. The instantaneous object is the sample itself."""
    drive, node = drive_on_bus(profile)
    averaged, instantaneous, rate = GENERATIONS[profile]
    period, slope = 0.004, 100_000.0                 # s, mA/s
    for _ in range(5):
        drive.update(0, 0, 0.0, period)
    assert _read(node, averaged) == 0
    a = math.exp(-2.0 * math.pi * CUTOFF / rate)
    checked = 0
    for k in range(1, 31):
        drive.update(0, 0, slope * k * period, period)
        if k % 3 == 0:
            n = k * period * rate                     # loop samples since the ramp began
            expected = slope / rate * (n - a * (1.0 - a**n) / (1.0 - a))
            assert abs(_read(node, averaged) - expected) <= 0.5 + 1e-6, (k, expected)
            assert _read(node, instantaneous) == round(slope * k * period)
            checked += 1
    lag = (slope * 30 * period - _read(node, averaged)) / slope   # s behind the ramp
    assert checked == 10 and abs(lag - (TAU - 0.5 / rate)) < 1e-5


@pytest.mark.parametrize("profile", ["epos4", "epos2"])
def test_the_averaged_current_of_a_sine_has_the_50_hz_filters_gain_and_lag(drive_on_bus, profile):
    """A 10 Hz sine of 2 A at a 1 kHz SYNC, once the start has died out, against the steady-state
    response of the 50 Hz first-order low-pass: gain ``1 / sqrt(1 + (f/fc)^2)`` (0.981), lag
    ``atan(f/fc)`` (11.3 degrees), by the digital filter's own frequency response at the loop
    rate. Tolerance: the whole-mA rounding and the linear interpolation between the 1 ms samples
    (at most ``A (w T)^2 / 8``, 1 mA). The continuous filter's response is as close but for the
    digital filter's lead of half a loop sample (at most ``A w / (2 rate)``: 3 mA at 10 kHz), the
    unfiltered sine 15 % of the amplitude away."""
    drive, node = drive_on_bus(profile)
    averaged, _, rate = GENERATIONS[profile]
    period, f, amplitude = 0.001, 10.0, 2000.0        # s, Hz, mA
    w = 2.0 * math.pi * f
    a = math.exp(-2.0 * math.pi * CUTOFF / rate)
    response = (1.0 - a) / (1.0 - a * np.exp(-1j * w / rate))       # the digital filter at w
    continuous = 1.0 / (1.0 + 1j * w * TAU)
    worst = worst_continuous = worst_raw = 0.0
    for k in range(400):
        t = k * period
        drive.update(0, 0, amplitude * math.sin(w * t), period)
        if k >= 200 and k % 10 == 0:
            got = _read(node, averaged)
            worst = max(worst, abs(got - amplitude * (response * np.exp(1j * w * t)).imag))
            worst_continuous = max(worst_continuous, abs(got - amplitude * (continuous * np.exp(1j * w * t)).imag))
            worst_raw = max(worst_raw, abs(got - amplitude * math.sin(w * t)))
    interpolation = amplitude * (w * period) ** 2 / 8
    assert worst <= 0.5 + interpolation + 1e-6
    assert worst_continuous <= 0.5 + interpolation + amplitude * w * 0.5 / rate and worst_raw > 0.15 * amplitude


@pytest.mark.parametrize("profile", ["epos4", "epos2"])
def test_the_averaged_object_saturates_at_its_data_type_and_starts_at_rest_after_a_reset(drive_on_bus, profile):
    """The EPOS2's 0x2027 is 16 bits: a 40 A current reads 32767 mA there; an NMT reset node
    (a reboot) restarts the average from rest."""
    drive, node = drive_on_bus(profile)
    averaged, _, _ = GENERATIONS[profile]
    for _ in range(50):
        drive.update(0, 0, 40_000.0, 0.004)
    assert _read(node, averaged) == (32767 if profile == "epos2" else 40_000)
    node.nmt.send_command(0x81)                                       # NMT reset node
    assert _wait(lambda: drive.get(*averaged) == 0 and drive.node.nmt.state == "PRE-OPERATIONAL")
    drive.update(0, 0, 0.0, 0.004)
    assert _read(node, averaged) == 0


def test_bus_current_chooses_the_object_of_tpdo1_and_a_bad_value_names_file_and_key(tmp_path):
    """``bus.current: averaged`` maps the averaged current into TPDO1 on either generation, in the
    place and size of the instantaneous one; the default stays the instantaneous sample; a value
    that is neither is refused naming the file, the key and the choices."""
    default = list(PlanInputs.of(load_config(SIM)).axes)
    assert {layout.frames[0].entries[1][1].subindex for layout in master_layouts(default)} == {2}   # 0x30D1:02
    config = tmp_path / "averaged.yaml"
    config.write_text(f"extends: {SIM}\nbus: {{current: averaged}}\n")
    loaded = load_config(config)
    assert loaded.current == "averaged"
    for axis in PlanInputs.of(loaded).axes:
        first = master_layouts([axis])[0].frames[0]
        assert [(f, r.index, r.subindex) for f, r in first.entries] == [("position", 0x6064, 0), ("current", 0x30D1, 1)]
    epos2 = AxisConfig("zeta1", 4, "epos2", nominal.PRISMATIC, -0.1, 0.1, 0.05, 4.0, 0.002, current="averaged")
    first = master_layouts([epos2])[0].frames[0]
    assert [(f, r.index) for f, r in first.entries] == [("position", 0x6064), ("current", 0x2027),
                                                         ("statusword", 0x6041)]
    assert first.size == master_layouts([AxisConfig("zeta1", 4, "epos2", nominal.PRISMATIC, -0.1, 0.1, 0.05, 4.0,
                                                    0.002)])[0].frames[0].size == 8

    bad = tmp_path / "bad.yaml"
    bad.write_text(f"extends: {SIM}\nbus:\n  current: filtered\n")
    with pytest.raises(ConfigError) as info:
        load_config(bad)
    message = str(info.value)
    assert "bad.yaml, line 3: bus.current:" in message and "'instantaneous'" in message and "'averaged'" in message
    with pytest.raises(DriverConfigError, match="axis 'zeta1': current must be one of"):
        AxisConfig("zeta1", 4, "epos2", nominal.PRISMATIC, -0.1, 0.1, 0.05, 4.0, 0.002, current="filtered")


def test_filtering_the_regressor_keeps_the_model_exact_for_averaged_forces():
    """Forces of the 3PRRR model along a smooth motion, averaged as a drive averages its current
    (by hand: the 25 kHz recursion on the forces interpolated linearly between the 4 ms samples),
    are the regressor put through :func:`ident_hw.filtering.running_average` times the parameters,
    to rounding: ``avg(Y pi) = avg(Y) pi``."""
    robot, truth = nominal.ROBOT, nominal.TRUE_PARAMS.as_vector()
    period, rate, n = 0.004, 25_000.0, 300
    t = np.arange(n) * period
    Theta = robot.home_actuated() + 0.05 * np.sin(2 * np.pi * 0.7 * t)[:, None] * np.array([1, 1, 1, 0.1, 0.1, 0.1])
    Thetad = 0.05 * 2 * np.pi * 0.7 * np.cos(2 * np.pi * 0.7 * t)[:, None] * np.array([1, 1, 1, 0.1, 0.1, 0.1])
    Thetadd = -(2 * np.pi * 0.7) ** 2 * (Theta - robot.home_actuated())
    Y, _ = robot.identification_regressor(Theta, Thetad, Thetadd, np.zeros(robot.pose_size))
    tau = Y @ truth
    a, steps = math.exp(-2 * math.pi * CUTOFF / rate), round(period * rate)
    by_hand = np.empty_like(tau)
    by_hand[0] = y = tau[0]
    for k in range(1, n):
        for i in range(1, steps + 1):
            y = a * y + (1 - a) * (tau[k - 1] + (tau[k] - tau[k - 1]) * i / steps)
        by_hand[k] = y
    matched = running_average(Y, [dataclasses.astuple(EPOS4.current_averaging.over_period(period))] * Y.shape[1]) @ truth
    np.testing.assert_allclose(matched, by_hand, rtol=0, atol=1e-9 * np.abs(tau).max())
    assert np.abs(by_hand - tau).max() > 0.01 * np.abs(tau).max()     # the average is not the force


def _sweep_config(folder: Path, current: str) -> Path:
    """The carriage sweep at 100 Hz (about 2,000 cycles), the carriage step on it, no current noise:
    the same motion whichever current is streamed (lockstep), so two runs compare sample by sample."""
    path = folder / f"sweep-{current}.yaml"
    path.write_text(
        f"extends: {SIM}\n"
        f"bus: {{channel: test-{os.getpid()}-{time.monotonic_ns()}, sync_rate: 100.0, current: {current}}}\n"
        "sim: {current_noise: 0.0}\n"
        "trajectories:\n  - {name: sweep, kind: carriage_sweep, size: 0.06}\n"
        "identification:\n"
        "  steps: [{name: carriages, trajectories: [sweep], parameters: [m_c, fv_zeta1, fv_zeta2, fv_zeta3,\n"
        "                                                                 fc_zeta1, fc_zeta2, fc_zeta3]}]\n"
        "  validation: []\n")
    return path


def _rows(folder: Path) -> dict:
    return {r["name"]: r for r in json.loads((folder / "parameters.json").read_text())["parameters"]}


@pytest.mark.slow
def test_a_campaign_on_averaged_currents_records_the_average_and_identifies_the_truth(tmp_path):
    """The carriage sweep run twice on the simulated rig, streaming the instantaneous then the
    averaged current. The second recording says it holds averaged currents and holds, to the
    drives' 1 mA, the first one's currents averaged by hand (the 25 kHz recursion, samples
    interpolated linearly). Identified from it, with the regressor through the same average,
    the carriage parameters are the truth within 3 sigma; the same recording taken for
    instantaneous currents (no matched filter) gives the viscous friction more than 30 % (and
    5 sigma) high: the force the 600 kg carriages' acceleration needs, delayed by the average's
    3 ms, looks like a force in phase with their velocity."""
    runs = {}
    for current in ("instantaneous", "averaged"):
        out = ident_hw("run", _sweep_config(tmp_path, current), "--out", tmp_path / current, "--quiet",
                       "--no-report", cwd=tmp_path)
        assert out.returncode == 0, out.stderr                     # the quality verdict passed
        runs[current] = Recording.load(tmp_path / current / "data" / "sweep.npz")
    plain, averaged = runs["instantaneous"], runs["averaged"]
    assert plain.metadata.current == "instantaneous" and averaged.metadata.current == "averaged"
    np.testing.assert_array_equal(averaged.position, plain.position)     # the same motion
    ma = plain.current * 1e3
    a, steps = math.exp(-2 * math.pi * CUTOFF / 25_000.0), 250          # 10 ms at 25 kHz
    y = ma[0].copy()
    by_hand = [y.copy()]
    for k in range(1, len(ma)):
        for i in range(1, steps + 1):
            y = a * y + (1 - a) * (ma[k - 1] + (ma[k] - ma[k - 1]) * i / steps)
        by_hand.append(y.copy())
    settled = slice(10, None)                                          # the filters' starts differ: 100 ms
    assert np.abs(averaged.current[settled] * 1e3 - np.array(by_hand)[settled]).max() <= 1.0 + 1e-6

    config = load_config(_sweep_config(tmp_path, "averaged"))
    truth = dict(zip(model_of(config.robot).parameter_names, true_parameters(config)))
    matched = _rows(tmp_path / "averaged")
    for name in ("m_c", "fv_zeta1", "fv_zeta2", "fv_zeta3", "fc_zeta1", "fc_zeta2", "fc_zeta3"):
        assert abs(matched[name]["identified"] - truth[name]) <= 3 * matched[name]["sigma"], (name, matched[name])
    # the recording says which current it holds: identified by a config saying instantaneous, it is refused
    out = ident_hw("identify", tmp_path / "instantaneous" / "config.yaml", tmp_path / "averaged" / "data" / "sweep.npz",
                   "--out", tmp_path / "refused", "--quiet", "--no-report", cwd=tmp_path)
    assert out.returncode == 5 and "holds the averaged current" in out.stderr, out.stderr
    # made to say instantaneous, it is identified without the matched filter
    averaged = dataclasses.replace(averaged, metadata=dataclasses.replace(
        averaged.metadata, current="instantaneous", axes=tuple(
            dataclasses.replace(a, current="instantaneous", current_filter=None) for a in averaged.metadata.axes)))
    (tmp_path / "unmatched").mkdir()
    averaged.save(tmp_path / "unmatched" / "sweep.npz")
    out = ident_hw("identify", tmp_path / "instantaneous" / "config.yaml", tmp_path / "unmatched" / "sweep.npz",
                   "--out", tmp_path / "unmatched-result", "--quiet", "--no-report", cwd=tmp_path)
    assert out.returncode in (0, 6), out.stderr
    unmatched = _rows(tmp_path / "unmatched-result")
    for name in ("fv_zeta1", "fv_zeta2", "fv_zeta3"):
        error = unmatched[name]["identified"] - truth[name]
        assert error > 5 * unmatched[name]["sigma"] and error > 0.3 * truth[name], (name, unmatched[name])
    # and the quality verdict sees it: the measured forces lag the model's
    status = (tmp_path / "unmatched-result" / "STATUS").read_text()
    assert out.returncode == 6 and "the measured forces lag the model's" in status, status
