"""The parts of an emulated drive without a bus: the CiA 402 state machine against canopen's own
State402 tables, the demand generators against closed-form motion, the object store against
a drive's dictionary."""

import dataclasses
import math

import numpy as np
import pytest
from canopen.profiles.p402 import State402

from drivers.cia import DISABLED, ENABLED, FAULT, FAULT_REACTION, NOT_READY, QUICK_STOP, READY, SWITCHED_ON
from drivers.profiles import EPOS2, EPOS4, make_object_dictionary
from drivers.sim.modes import Demand, cyclic_segment, profile_step, ramp_down
from drivers.sim.objects import ObjectStore
from drivers.sim.state_machine import next_state, statusword

COMMANDED = (DISABLED, READY, SWITCHED_ON, ENABLED, QUICK_STOP)


def test_every_transition_of_canopens_table_is_taken_by_its_controlword():
    """canopen's master walks the states with State402.TRANSITIONTABLE; the emulated drive must
    go where that table expects for each command."""
    checked = 0
    for (start, end), controlword in State402.TRANSITIONTABLE.items():
        if start not in COMMANDED or end not in COMMANDED:
            continue        # START, NOT READY, FAULT (REACTION), the fault reset edge: the drive's own
        assert next_state(start, controlword) == end, (start, hex(controlword), end)
        checked += 1
    assert checked >= 11


@pytest.mark.parametrize("state", COMMANDED)
def test_a_command_not_allowed_in_a_state_leaves_it(state):
    """CiA 402: switch on from SWITCH ON DISABLED, enable operation from SWITCH ON DISABLED, a
    quick stop outside OPERATION ENABLED keep (or drop) the state, never skip ahead."""
    if state == DISABLED:
        assert next_state(state, 0x07) == DISABLED and next_state(state, 0x0F) == DISABLED
    assert next_state(state, 0x00) == DISABLED          # disable voltage from anywhere
    if state in (READY, SWITCHED_ON):
        assert next_state(state, 0x02) == DISABLED      # quick stop without power: disabled
    if state == QUICK_STOP:
        assert next_state(state, 0x06) == QUICK_STOP and next_state(state, 0x07) == QUICK_STOP


@pytest.mark.parametrize("state", [NOT_READY, DISABLED, READY, SWITCHED_ON, ENABLED, QUICK_STOP,
                                   FAULT_REACTION, FAULT])
def test_the_statusword_decodes_to_its_state_with_canopens_masks(state):
    mask, value = State402.SW_MASK[state]
    for mode_bits, homed in ((0, False), (0x1400, True)):
        sw = statusword(state, mode_bits, homed)
        assert sw & mask == value
        assert [name for name, (m, v) in State402.SW_MASK.items() if sw & m == v] == [state]
        assert bool(sw & 0x0010) == (state not in (NOT_READY, DISABLED))     # bit 4 voltage enabled
        assert sw & 0x0200                                                    # bit 9 remote
        assert bool(sw & 0x8000) == homed                                     # maxon bit 15 homed


def _cubic(demand: Demand, t):
    c0, c1, c2, c3 = demand.coefficients()
    return c0 + c1 * t + c2 * t**2 + c3 * t**3, c1 + 2 * c2 * t + 3 * c3 * t**2, 2 * c2 + 6 * c3 * t


def test_cyclic_segments_follow_a_line_exactly_and_join_with_c2_continuity():
    """Targets on a line give the line (B-spline reproduces linear data); arbitrary targets give
    a demand whose position, velocity and acceleration are continuous from period to period."""
    period = 0.004
    demand, history = Demand(position=100.0), None
    for k in range(6):                          # settle on the held position, then a ramp
        history = cyclic_segment(demand, 100.0, period, history)
        demand.advance(period)
    rng = np.random.default_rng(3)
    line = 100.0 + 2500.0 * period * np.arange(1, 40)
    targets = np.concatenate([line, line[-1] + np.cumsum(rng.normal(0, 5, 40))])
    ends = None
    for k, target in enumerate(targets):
        history = cyclic_segment(demand, float(target), period, history)
        starts = _cubic(demand, 0.0)
        if ends is not None:
            np.testing.assert_allclose(starts, ends, rtol=1e-9, atol=1e-6)
        if 8 <= k < 39:                         # three targets into the line: on it, at its speed
            assert starts[1] == pytest.approx(2500.0) and abs(starts[2]) < 1e-6
            assert starts[0] == pytest.approx(line[k - 2])     # the spline lags two targets
        ends = _cubic(demand, period)
        demand.advance(period)
        assert (demand.position, demand.velocity) == pytest.approx(ends[:2], rel=1e-12, abs=1e-9)


def test_a_profile_move_is_the_trapezoid_of_its_speed_and_acceleration():
    """From rest to rest over 10,000 counts at 2,000 counts/s and 5,000 counts/s²: the demand
    lands on the target at rest after d/v + v/a = 5.4 s, never faster than the speed, and
    the acceleration of each period's cubic stays within the profile's (within one period's
    braking correction)."""
    period, speed, accel, target = 0.01, 2000.0, 5000.0, 10000.0
    demand, steps, arrived = Demand(), 0, False
    while not arrived:
        arrived = profile_step(demand, target, speed, accel, period)
        _, v_mid, a_start = _cubic(demand, 0.5 * period)
        assert abs(v_mid) <= speed * (1 + 1e-9)
        assert abs(_cubic(demand, 0.0)[2]) <= 1.5 * accel and abs(_cubic(demand, period)[2]) <= 1.5 * accel
        demand.advance(period)
        steps += 1
        assert steps < 1000
    assert demand.position == target and demand.velocity == pytest.approx(0.0, abs=1e-6)
    assert steps * period == pytest.approx(target / speed + speed / accel, abs=2 * period)


def test_ramp_down_stops_within_the_distance_of_uniform_deceleration():
    period, v0, decel = 0.002, 3000.0, 60000.0
    demand = Demand(position=0.0, velocity=v0)
    periods = 0
    while demand.velocity:
        ramp_down(demand, decel, period)
        demand.advance(period)
        periods += 1
    assert periods == math.ceil(v0 / (decel * period))
    assert demand.position == pytest.approx(v0**2 / (2 * decel), rel=1e-9)   # v0/(decel T) = 25 periods exactly


def test_the_object_store_reads_defaults_writes_and_objects_a_drive_lacks():
    for profile in (EPOS2, EPOS4):
        store = ObjectStore(make_object_dictionary(profile.name, 1))
        default = store.dictionary.get_variable(profile.statusword.index, profile.statusword.subindex).default
        assert store[profile.statusword] == default
        store[profile.statusword] = 0x0237
        assert store.get(profile.statusword.index, profile.statusword.subindex) == 0x0237
    for name in ("epos2", "epos4"):                                # no cycle period, no PDO event timer
        store = ObjectStore(make_object_dictionary(name, 1))
        assert not store.has(0x1006) and store.optional(0x1006, default=-1) == -1
        assert not store.has(0x1400, 5) and store.has(0x1400, 2)
        # an array holds only the sub-indices it defines (canopen would make up the others)
        assert store.has(0x1003, 5) and not store.has(0x1003, 6) and store.optional(0x1003, 6, default=-1) == -1
    watching = ObjectStore(make_object_dictionary(dataclasses.replace(EPOS2, pdo_event_timer=True), 1))
    assert watching.has(0x1400, 5) and watching.optional(0x1400, 5, default=-1) == 0   # a variant with a deadline
