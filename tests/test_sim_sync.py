"""Time in the cyclic mode is the SYNC's; a streaming drive faults on missing set-points (RPDO timeout).

A real canopen master streams the start of the carriage sweep to six emulated drives in their
cyclic position mode, in lockstep (as in ``test_sim_cyclic``), and stalls as a loaded host would:
it sleeps between the set-points of one cycle and their SYNC. With SYNC-driven time the stall
changes nothing: the run is identical, sample for sample, to the same run without the stall (no
idle plant steps, no following error). The RPDO deadline (``0x1400:05``, EMCY ``0x8250``) fires
only when the set-points stop for longer than it, and a stall of the rig's own thread (a host
hiccup) is not counted. Neither EPOS has that deadline: the drives here are EPOS2 with it added
(:data:`WATCHING`).
"""

import dataclasses
import time

import numpy as np
import pytest

from drivers.profiles import EPOS2
import nominal
from ident_hw.model import ThreePRRR
from trajectories.feasibility import Limits
from trajectories.paper import carriage_sweep

from test_sim_cyclic import COUNTS_PER_UNIT, PERIOD, stream_lockstep
from test_sim_faults import collect_emcy
from test_sim_rig import Bench, wait_until

ROBOT = ThreePRRR(nominal.GEOMETRY)
N_ROWS = 250            # 1 s of the sweep: carriage 1 accelerates to 0.09 m/s
STALL_AT = 150          # carriage 1 at ~0.09 m/s: 0.36 mm (360 counts) per period
RPDO_TIMEOUT = 0x8250
#: drives that watch their set-points: the RPDO deadline 0x140x:05 of CiA 301, which neither the
#: EPOS2 nor the EPOS4 has (maxon's files: no sub-index 5), on a variant of the EPOS2 profile
WATCHING = dataclasses.replace(EPOS2, pdo_event_timer=True)


@pytest.fixture(scope="module")
def targets():
    traj = carriage_sweep(ROBOT, Limits(), rate=1.0 / PERIOD)
    return np.rint((traj.Theta[:N_ROWS] - traj.Theta[0]) * COUNTS_PER_UNIT)


def run(targets, stall=0.0, stall_at=STALL_AT, deadline_ms=0, stall_rig=False):
    """Stream ``targets``; the master sleeps ``stall`` s before SYNC ``stall_at`` (holding the rig's
    lock with ``stall_rig``: the rig's own thread stalls too). Returns what the master saw."""
    bench = Bench(profiles=(WATCHING,) * 6, sync_period=PERIOD, seed=1)
    try:
        bench.rig.start()
        codes = {n.id: collect_emcy(n) for n in bench.nodes}

        def before_sync(k):
            if k == stall_at and stall:
                if stall_rig:
                    with bench.rig._lock:
                        time.sleep(stall)
                else:
                    time.sleep(stall)

        counts, milliamps = stream_lockstep(bench, targets, before_sync, deadline_ms)
        assert wait_until(lambda: bench.rig.syncs_done == bench.rig.sync_count)
        # what the stream raised: the EMCYs sent before the last set-point's deadline ran out
        # (after it, a watching drive faults as it should: the set-points have stopped)
        time.sleep(min(0.05, 0.5 * deadline_ms * 1e-3) if deadline_ms else 0.05)
        codes = {node: list(seen) for node, seen in codes.items()}
        truth = {k: v[-len(targets):] for k, v in bench.rig.plant.truth().items()}
        return dict(counts=counts, milliamps=milliamps, truth=truth, codes=codes,
                    states=[d.state for d in bench.rig.drives], n_steps=len(bench.rig.plant.log))
    finally:
        bench.close()


def test_a_stalled_master_stalls_the_plant_and_the_run_is_unchanged(targets):
    reference = run(targets)
    stalled = run(targets, stall=0.2, deadline_ms=500)
    for result in (reference, stalled):
        assert all(c == [] for c in result["codes"].values()), result["codes"]     # no 0x8611, no 0x8250
        assert result["states"] == ["OPERATION ENABLED"] * 6
        # simulated time advanced by one period per SYNC, during the stall too
        np.testing.assert_allclose(np.diff(result["truth"]["t"]), PERIOD, rtol=1e-9)
    # the plant did not move during the 0.2 s (50 periods) stall: what the drives reported, and
    # the plant's own motion, are those of the run without it
    np.testing.assert_array_equal(stalled["counts"], reference["counts"])
    np.testing.assert_array_equal(stalled["milliamps"], reference["milliamps"])
    np.testing.assert_array_equal(stalled["truth"]["Theta"], reference["truth"]["Theta"])
    moving = np.abs(np.diff(reference["counts"][:, 3]))[STALL_AT - 1]
    print(f"carriage 1 at the stall: {moving:.0f} counts per period; plant steps {stalled['n_steps']}")
    assert moving > 300


def test_rpdo_timeout_fires_only_when_set_points_stop_for_longer_than_the_deadline(targets):
    deadline = 0.1
    # a 60 ms stall (15 periods) with a 100 ms deadline: no fault
    short = run(targets[:60], stall=0.06, stall_at=30, deadline_ms=int(deadline * 1e3))
    assert all(c == [] for c in short["codes"].values()) and short["states"] == ["OPERATION ENABLED"] * 6
    # a 0.3 s stall of the rig's own thread (a host hiccup, the lock held): not counted either
    hiccup = run(targets[:60], stall=0.3, stall_at=30, deadline_ms=int(deadline * 1e3), stall_rig=True)
    assert all(c == [] for c in hiccup["codes"].values()) and hiccup["states"] == ["OPERATION ENABLED"] * 6
    # the master stops: every drive signals the RPDO timeout and ends in FAULT
    bench = Bench(profiles=(WATCHING,) * 6, sync_period=PERIOD, seed=1)
    try:
        bench.rig.start()
        arrivals = {}
        for node in bench.nodes:
            node.emcy.add_callback(lambda err, i=node.id: arrivals.setdefault(i, (err.code, time.monotonic())))
        stream_lockstep(bench, targets[:40], rpdo_deadline_ms=int(deadline * 1e3))
        stopped = time.monotonic()
        assert wait_until(lambda: len(arrivals) == 6, timeout=2.0), arrivals
        assert wait_until(lambda: [d.state for d in bench.rig.drives] == ["FAULT"] * 6)
        assert bench.nodes[0].sdo[0x1003][1].raw == RPDO_TIMEOUT          # the newest error (no 0x603F)
    finally:
        bench.close()
    delays = np.array([arrivals[n][1] - stopped for n in sorted(arrivals)])
    print("RPDO timeout after the last SYNC (s):", np.round(delays, 3))
    assert {code for code, _ in arrivals.values()} == {RPDO_TIMEOUT}
    # not before the deadline (the rig's clock runs at most as fast as the wall clock; the last
    # set-point is stamped at the rig's last tick, up to one tick before the SYNC)
    assert np.all(delays > deadline - 0.011)
