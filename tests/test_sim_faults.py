"""Modes, NMT and fault injection of the simulated rig, seen by a REAL canopen master (virtual bus)."""

import threading
import time

import canopen
import numpy as np
import pytest
from canopen.nmt import NmtError
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from drivers.sim.drive import EmulatedDrive
from test_sim_rig import PRI, REV, Bench, configure_pdos, wait_until

SW_TARGET_REACHED, SW_BIT12, SW_STATE_MASK = 0x0400, 0x1000, 0x006F


def enable(node, mode):
    node.sdo[0x6060].raw = mode
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[0x6040].raw = cw
    assert node.sdo[0x6041].raw & SW_STATE_MASK == 0x0027          # OPERATION ENABLED


def collect_emcy(node):
    codes = []
    node.emcy.add_callback(lambda err: codes.append(err.code))
    return codes


@pytest.fixture
def bench(request):
    b = Bench(**getattr(request, "param", {}))
    b.rig.start()
    yield b
    b.close()


@pytest.mark.parametrize("profile, method, home_index", [("epos4", 37, 0x30B0), ("epos2", 35, 0x2081)])
def test_homing_on_the_actual_position_assigns_the_home_position(profile, method, home_index):
    b = Bench(profiles=(profile,) * 6)
    try:
        b.rig.start()
        node = b.nodes[3]
        node.sdo[home_index].raw = 12345
        node.sdo[0x6098].raw = method
        enable(node, 6)
        node.sdo[0x6040].raw = 0x1F                                   # start homing
        assert wait_until(lambda: node.sdo[0x6041].raw & (SW_BIT12 | SW_TARGET_REACHED)
                          == SW_BIT12 | SW_TARGET_REACHED)
        assert abs(node.sdo[0x6064].raw - 12345) <= 2
        assert abs(b.nodes[4].sdo[0x6064].raw) <= 2                   # the others are untouched
    finally:
        b.close()


def test_homing_with_a_search_move_travels_and_comes_back(bench):
    node, plant = bench.nodes[0], bench.rig.plant
    start = plant.Theta[0]
    node.sdo[0x30B0].raw = -500
    node.sdo[0x6098].raw = 1                                          # index search, negative direction
    node.sdo[0x6099][1].raw = 600                                     # rpm
    node.sdo[0x6099][2].raw = 600
    node.sdo[0x609A].raw = 20000                                      # rpm/s
    enable(node, 6)
    node.sdo[0x6040].raw = 0x1F
    assert wait_until(lambda: node.sdo[0x6041].raw & SW_BIT12, timeout=5.0)
    travel = REV.position_from_counts(0.5 * REV.counts_per_turn)      # the emulated search: half a motor turn
    moved = plant.truth()["Theta"][:, 0] - start
    assert moved.min() < -0.9 * travel                                # it went (negative for an odd method) ...
    # ... and came back: "homing attained" comes with the demand, the axis settles after it
    assert wait_until(lambda: abs(plant.Theta[0] - start) < 0.01 * travel)
    assert wait_until(lambda: abs(node.sdo[0x6064].raw + 500) <= 0.01 * REV.counts_per_turn)


def test_profile_position_set_point_acknowledge_target_reached_and_limited_target(bench):
    node = bench.nodes[4]
    codes = collect_emcy(node)
    target = PRI.counts_from_position(0.002)                          # 2 mm
    node.sdo[0x6081].raw = 300                                        # profile velocity, rpm
    node.sdo[0x6083].raw = 500                                        # acceleration, rpm/s
    node.sdo[0x6084].raw = 500
    # a steady push against the motion (N): the carriage ends a few counts behind its demand. Without
    # it, the end of the second move below sits on the software limit, where the loop's settling
    # overshoot of a count or two faults the drive, as moving onto a limit can fault a real one
    bench.rig.set_external_force([0, 0, 0, 0, -60.0, 0])
    enable(node, 1)
    node.sdo[0x607A].raw = target
    node.sdo[0x6040].raw = 0x1F                                       # new set-point
    assert node.sdo[0x6041].raw & SW_BIT12                            # set-point acknowledged
    node.sdo[0x6040].raw = 0x0F
    assert not node.sdo[0x6041].raw & SW_BIT12                        # acknowledge follows bit 4
    assert wait_until(lambda: node.sdo[0x6041].raw & SW_TARGET_REACHED, timeout=3.0)
    assert wait_until(lambda: abs(node.sdo[0x6064].raw - target) <= 0.01 * target)   # settles behind the demand
    # a target beyond the software position limit: the demand stops at the limit (CiA 402)
    node.sdo[0x607D][2].raw = 2 * target
    node.sdo[0x607A].raw = 10 * target
    node.sdo[0x6040].raw = 0x1F
    node.sdo[0x6040].raw = 0x0F
    assert wait_until(lambda: node.sdo[0x6041].raw & SW_TARGET_REACHED, timeout=3.0), [hex(c) for c in codes]
    assert wait_until(lambda: node.sdo[0x6062].raw == 2 * target)    # demand value, one cycle behind
    assert codes == []


@pytest.mark.parametrize("distance", [3000, 40000])                  # counts: triangle, trapezoid
def test_profile_position_demand_is_the_trapezoid_and_arrives_at_rest(distance):
    """The emulated drive's demand, stepped period by period on an ideal axis, checked by finite
    differences against the trapezoid it must be: speed within 0x6081, acceleration within 0x6083,
    at rest on the target, in the textbook move time."""
    drive = EmulatedDrive(5, "epos4", PRI, canopen.Network(), threading.RLock(), lambda: 0.0)
    sdo = drive.node.sdo
    rpm, rpm_per_s, period = 300, 500, 0.004
    sdo[0x6081].raw, sdo[0x6083].raw, sdo[0x6084].raw = rpm, rpm_per_s, rpm_per_s
    sdo[0x6060].raw = 1
    for cw in (0x06, 0x07, 0x0F, 0x1F, 0x0F):
        sdo[0x607A].raw = distance
        sdo[0x6040].raw = cw
    q = []
    for _ in range(int(5.0 / period)):
        drive.plan(period)
        q.append(drive.demand)
        drive.update(int(round(drive.demand)), 0, 0, period)
    q = np.array(q)
    v, a = np.diff(q) / period, np.diff(q, 2) / period**2
    vmax, acc = rpm * PRI.counts_per_turn / 60, rpm_per_s * PRI.counts_per_turn / 60     # counts/s, /s^2
    assert q[-1] == distance and drive.demand_velocity == 0 and sdo[0x6041].raw & SW_TARGET_REACHED
    assert v.max() <= vmax * (1 + 1e-9) and v.min() >= 0
    far = distance - q[1:-1] > 2                                        # the last two counts snap to the target
    assert np.abs(a[far]).max() <= 1.05 * acc
    assert v[distance - q[1:] <= 2].max() <= np.sqrt(2 * acc * 3)       # no step down to rest
    arrival = np.argmax(q == distance) * period
    ideal = 2 * np.sqrt(distance / acc) if distance < vmax**2 / acc else distance / vmax + vmax / acc
    assert abs(arrival - ideal) <= 3 * period


@pytest.mark.parametrize("profile, code", [("epos4", 0x8A82), ("epos2", 0xFF09)])
def test_position_outside_the_software_limits_faults_with_the_generation_code(profile, code):
    b = Bench(profiles=(profile,) * 6)
    try:
        b.rig.start()
        node = b.nodes[1]
        codes = collect_emcy(node)
        node.sdo[0x607D][1].raw = 100                                 # the axis stands at 0 counts
        node.sdo[0x607D][2].raw = 200
        node.sdo[0x6060].raw = 1
        for cw in (0x06, 0x07, 0x0F):
            node.sdo[0x6040].raw = cw
        assert wait_until(lambda: b.rig.faulted() == [2])
        assert wait_until(lambda: codes == [code])
        assert node.sdo[0x1003][1].raw == code and node.sdo[0x1001].raw            # newest error, present
        if profile == "epos4":                                          # the EPOS2 has no 0x603F
            assert node.sdo[0x603F].raw == code
    finally:
        b.close()


def test_silenced_node_stops_its_heartbeat_and_answers_nothing_until_revived(bench):
    node = bench.nodes[2]
    node.sdo[0x1017].raw = 20
    node.nmt.wait_for_heartbeat(0.5)
    node.sdo.RESPONSE_TIMEOUT = 0.2
    bench.rig.silence(3)
    time.sleep(0.05)
    with pytest.raises(NmtError):
        node.nmt.wait_for_heartbeat(0.2)                              # the master's heartbeat consumer sees it
    with pytest.raises(SdoCommunicationError):
        node.sdo[0x1018][1].raw
    bench.rig.silence(3, False)
    assert node.nmt.wait_for_heartbeat(0.5) == "PRE-OPERATIONAL"
    assert node.sdo[0x1018][1].raw == 0xFB


def test_injected_sdo_abort_is_seen_with_its_code_and_can_be_removed(bench):
    node = bench.nodes[0]
    bench.rig.sdo_abort(1, 0x6065, 0, 0x08000022)                    # "not in the present device state"
    for access in (lambda: node.sdo[0x6065].raw, lambda: setattr(node.sdo[0x6065], "raw", 5)):
        with pytest.raises(SdoAbortedError) as err:
            access()
        assert err.value.code == 0x08000022
    assert bench.nodes[1].sdo[0x6065].raw == 2000                     # other nodes unaffected
    bench.rig.sdo_abort(1, 0x6065, 0, None)
    node.sdo[0x6065].raw = 5
    assert node.sdo[0x6065].raw == 5


def _stream(bench, seconds, period=0.004):
    counts = {}
    for node in bench.nodes:
        configure_pdos(node, "EPOS4")
        counts[node.id] = []
        node.tpdo[1].add_callback(lambda m, i=node.id: counts[i].append(m.timestamp))
    bench.master.nmt.state = "OPERATIONAL"
    time.sleep(0.05)
    bench.master.sync.start(period)
    time.sleep(seconds)
    bench.master.sync.stop()
    time.sleep(0.1)
    return counts


@pytest.mark.parametrize("bench", [{"seed": 7, "sync_period": 0.004}], indirect=True)
def test_dropped_frames_follow_the_drop_probability_on_the_chosen_nodes(bench):
    bench.rig.frame_faults(drop_probability=0.3, node_ids=[2])
    counts = _stream(bench, 1.0)
    syncs = bench.rig.sync_count
    n = {i: len(c) for i, c in counts.items()}
    assert all(n[i] == syncs for i in (1, 3, 4, 5, 6)), (n, syncs)
    assert 0.6 * syncs < n[2] < 0.8 * syncs, (n[2], syncs)
    assert bench.rig.network.dropped >= syncs - n[2]


def test_delayed_frames_arrive_after_the_delay(bench):
    node = bench.nodes[0]
    configure_pdos(node, "EPOS4")
    arrivals = []
    node.tpdo[1].add_callback(lambda m: arrivals.append(time.monotonic()))
    bench.master.nmt.state = "OPERATIONAL"
    time.sleep(0.05)
    bench.rig.frame_faults(delay=0.08, node_ids=[1])
    sent = time.monotonic()
    bench.master.sync.transmit()
    assert wait_until(lambda: arrivals, timeout=1.0)
    assert 0.08 <= arrivals[0] - sent < 0.2
    bench.rig.frame_faults()                                          # healed: next one at once
    sent = time.monotonic()
    bench.master.sync.transmit()
    assert wait_until(lambda: len(arrivals) == 2, timeout=1.0)
    assert arrivals[1] - sent < 0.05


@pytest.mark.parametrize("bench", [{"initial_states": {2: "FAULT", 5: "STOPPED"}}], indirect=True)
def test_drives_in_the_wrong_state_at_start(bench):
    assert wait_until(lambda: len(bench.boot_states) == 6)
    faulted = bench.nodes[1]
    assert faulted.sdo[0x6041].raw & 0x004F == 0x0008                 # statusword FAULT
    assert faulted.sdo[0x1003][1].raw == 0x1000 and faulted.sdo[0x1001].raw & 0x01
    assert bench.rig.faulted() == [2]
    stopped = bench.nodes[4]
    stopped.nmt.state = "PRE-OPERATIONAL"                             # the master's way out ...
    stopped.sdo[0x1017].raw = 20                                      # ... after which SDO answers
    assert stopped.nmt.wait_for_heartbeat(0.5) == "PRE-OPERATIONAL"


@pytest.mark.parametrize("bench", [{"initial_states": {5: "STOPPED"}}], indirect=True)
def test_stopped_drive_does_not_answer_sdo(bench):
    node = bench.nodes[4]
    node.sdo.RESPONSE_TIMEOUT = 0.2
    with pytest.raises(SdoCommunicationError):
        node.sdo[0x1018][1].raw


def test_nmt_reset_node_and_reset_communication(bench):
    node = bench.nodes[3]
    node.sdo[0x30B0].raw = 4000                                       # home here at 4000 counts
    node.sdo[0x6098].raw = 37
    enable(node, 6)
    node.sdo[0x6040].raw = 0x1F
    assert wait_until(lambda: abs(node.sdo[0x6064].raw - 4000) <= 2)
    node.sdo[0x6040].raw = 0x06
    node.sdo[0x1017].raw = 20
    node.sdo[0x6065].raw = 1234
    # reset communication: communication objects back to defaults, application kept
    booted = []
    node.nmt.add_heartbeat_callback(lambda state: booted.append(state))
    node.nmt.state = "RESET COMMUNICATION"
    assert wait_until(lambda: 0 in booted)
    assert node.sdo[0x1017].raw == 0 and node.sdo[0x6065].raw == 1234
    assert abs(node.sdo[0x6064].raw - 4000) <= 2
    # reset node: everything back to defaults, the incremental encoder counts from 0 again
    booted.clear()
    node.nmt.state = "RESET"
    assert wait_until(lambda: 0 in booted)
    assert node.sdo[0x6065].raw == 2000
    assert abs(node.sdo[0x6064].raw) <= 2
    assert node.sdo[0x6041].raw & SW_STATE_MASK == 0x0040             # SWITCH ON DISABLED


def test_short_rpdo_raises_the_pdo_length_emcy_without_a_fault(bench):
    node = bench.nodes[0]
    codes = collect_emcy(node)
    configure_pdos(node, "EPOS4")                                     # RPDO1 = 0x607A + 0x6040 (6 bytes)
    bench.master.nmt.state = "OPERATIONAL"
    time.sleep(0.05)
    bench.master.send_message(0x201, b"\x01\x02")
    assert wait_until(lambda: codes == [0x8210])
    assert bench.rig.faulted() == []
    assert node.sdo[0x1003][1].raw == 0x8210


@pytest.mark.parametrize("bench", [{"profiles": ("epos2",) * 6}], indirect=True)   # read-only on an EPOS4
def test_emcy_cob_id_follows_0x1014_with_cia301_rules(bench):
    node = bench.nodes[0]
    seen = []
    bench.master.subscribe(0x0F1, lambda can_id, data, ts: seen.append(data))
    codes = collect_emcy(node)
    with pytest.raises(SdoAbortedError) as err:
        node.sdo[0x1014].raw = 0x0F1                                  # CAN-ID change while valid
    assert err.value.code == 0x06090030
    node.sdo[0x1014].raw = 0x80000081                                 # invalid: no EMCY at all
    bench.rig.emcy(1, 0x2310)
    time.sleep(0.1)
    assert codes == [] and bench.rig.faulted() == [1]
    node.sdo[0x1014].raw = 0x800000F1
    node.sdo[0x1014].raw = 0x000000F1                                 # valid again, on 0xF1
    bench.rig.emcy(1, 0x3210)
    assert wait_until(lambda: seen)
    assert int.from_bytes(seen[0][:2], "little") == 0x3210 and codes == []


def test_commanded_into_a_singularity_every_enabled_drive_faults_with_a_following_error(bench):
    """Links 1-3 turned together by 0.3 rad cross the platform's type II singularity (~0.175 rad)."""
    codes = {n.id: collect_emcy(n) for n in bench.nodes}
    turn = REV.counts_from_position(0.3)
    for node in bench.nodes:
        node.sdo[0x6065].raw = 0xFFFFFFFF                             # following-error check off
        node.sdo[0x6081].raw = 300
        enable(node, 1)
    for node in bench.nodes[:3]:
        node.sdo[0x607A].raw = turn
        node.sdo[0x6040].raw = 0x1F
    assert wait_until(lambda: bench.rig.jammed is not None, timeout=5.0)
    assert wait_until(lambda: sorted(bench.rig.faulted()) == [1, 2, 3, 4, 5, 6])
    assert all(wait_until(lambda c=c: 0x8611 in c) for c in codes.values())
    assert "jammed" in bench.rig.jammed
    # the jam put the plant back at rest (the step after it starts from Thetad = 0 exactly);
    # afterwards the drives' fault reaction and then the free mechanism may move it again
    def rested_after_moving():
        with bench.rig._lock:
            moving = np.any(bench.rig.plant.truth()["Thetad"] != 0, axis=1)
        return moving.any() and not moving[np.argmax(moving):].all()
    assert wait_until(rested_after_moving)


MASTER_ID = 100


def test_lost_master_heartbeat_faults_the_watching_drives_with_a_quick_stop_ramp(bench):
    """0x1016:01 = producer 100, 100 ms: the watch starts with the first heartbeat; when it stops,
    EMCY 0x8130, fault reaction (quick-stop ramp at 0x6085, statusword 0x000F), then FAULT."""
    moving, other_producer, unwatched = bench.nodes[3], bench.nodes[4], bench.nodes[5]
    codes = {n.id: collect_emcy(n) for n in bench.nodes[3:]}
    moving.sdo[0x1016][1].raw = MASTER_ID << 16 | 100
    other_producer.sdo[0x1016][1].raw = (MASTER_ID + 1) << 16 | 100    # never heard: never armed
    heartbeat = bench.master.send_periodic(0x700 + MASTER_ID, [0x05], 0.02)
    try:
        for node in (moving, other_producer, unwatched):
            enable(node, 1)
        moving.sdo[0x6081].raw = 1000                                   # rpm: 33 mm/s on the screw
        moving.sdo[0x6083].raw = 20000
        moving.sdo[0x6085].raw = 2000                                   # quick stop: 2000 rpm/s = 67 mm/s^2
        moving.sdo[0x607A].raw = PRI.counts_from_position(0.08)
        moving.sdo[0x6040].raw = 0x1F                                   # new set-point
        plant, axis = bench.rig.plant, 3
        assert wait_until(lambda: plant.Thetad[axis] > 0.03, timeout=3.0)
        time.sleep(0.2)
        assert all(c == [] for c in codes.values()) and bench.rig.faulted() == []
    finally:
        heartbeat.stop()
    lost = time.monotonic()
    speed, start = plant.Thetad[axis], plant.Theta[axis]
    assert wait_until(lambda: codes[moving.id] == [0x8130], timeout=1.0)
    assert 0.1 - 0.02 <= time.monotonic() - lost < 0.5                 # last heartbeat <= 20 ms before
    sw = moving.sdo[0x6041].raw
    assert sw & 0x004F == 0x000F, hex(sw)                              # FAULT REACTION ACTIVE: braking
    assert wait_until(lambda: bench.rig.drive(moving.id).state == "FAULT", timeout=2.0)
    assert moving.sdo[0x603F].raw == 0x8130 and moving.sdo[0x1003][1].raw == 0x8130
    assert moving.sdo[0x1001].raw & 0x10                               # communication error bit
    # stopped by the ramp: v^2 / 2a (8 mm from 33 mm/s) plus the travel during the 0.1 s timeout
    ramp = speed**2 / (2 * 2000 / 60 * PRI.screw_lead)
    travelled = plant.Theta[axis] - start
    assert abs(plant.Thetad[axis]) < 1e-3 and ramp < travelled < ramp + 0.5 * speed, (travelled, ramp)
    # only the drive that heard the producer faulted
    assert bench.rig.faulted() == [moving.id]
    assert codes[other_producer.id] == [] and codes[unwatched.id] == []
