"""A run on a disturbed SYNC, as on a real bus behind a busy host: the simulated rig in real time
(its drives move on their own clock between two SYNCs) and the master's thread-timed SYNC
producer held up now and then, so that about a fifth of its slots are skipped. Every try ends
with each well-identified parameter within 5 % of the truth, or ``degraded``, or stopped by a
drive that ran out of its following-error window (set-points too late, as on a real rig): never
with a wrong result marked good."""

from __future__ import annotations

import logging
import os
import threading
import time

import numpy as np
import pytest

from drivers import bus as bus_module
from drivers.cia import SYNC_COB_ID
from ident_hw.config import load_config
from ident_hw.experiment import runner
from ident_hw.experiment.session import HostSettings
from ident_hw.experiment.folders import new_results_folder
from ident_scenarios import CONFIGS, SWEEP_CAMPAIGN, without_draws

log = logging.getLogger(__name__)

#: a SYNC slot is followed, with this probability, by a hold-up of the producer thread of
#: one to three periods (each skipping that many slots): about 20 % of the slots skipped
STALL_PROBABILITY = float(os.environ.get("STALL", "0.1"))

#: the carriage sweep at half the paper's size: 10 s of real time per try instead of 20 s. What is
#: checked is the verdict on a disturbed SYNC; the sweep's parameters are known to far better than
#: the 5 % asked from it
HALF_SWEEP = SWEEP_CAMPAIGN.replace("size: 0.06", "size: 0.03")


class _HeldUpEvent(threading.Event):
    """The producer thread's stop event, whose waits now and then last 1-3 periods longer (a host
    that does not schedule the thread in time)."""

    def __init__(self, period: float, seed: int):
        super().__init__()
        self._period = period
        self._rng = np.random.default_rng(seed)

    def wait(self, timeout=None):
        if timeout is not None and self._rng.random() < STALL_PROBABILITY:
            timeout += self._period * self._rng.integers(1, 4)
        return super().wait(timeout)


def _disturb_sync(monkeypatch, seed: int) -> None:
    real = bus_module.BusNetwork.send_periodic

    def send_periodic(self, can_id, data, period, remote=False):
        task = real(self, can_id, data, period, remote)
        if can_id == SYNC_COB_ID and isinstance(task, bus_module.GridPeriodicTask):
            task._stop = _HeldUpEvent(period, seed)
        return task
    monkeypatch.setattr(bus_module.BusNetwork, "send_periodic", send_periodic)


@pytest.mark.slow
@pytest.mark.parametrize("attempt", [1, 2, 3])
def test_a_disturbed_sync_ends_within_5_percent_or_degraded(tmp_path, monkeypatch, attempt):
    path = tmp_path / "disturbed.yaml"
    path.write_text(
        f"extends: {CONFIGS / 'sim-3prrr.yaml'}\n"
        f"bus: {{interface: virtual, channel: disturbed-{os.getpid()}-{time.monotonic_ns()}, sync_rate: 250.0, "
        "sync: periodic}\n" + HALF_SWEEP)
    config = without_draws(load_config(path))    # the verdict is checked, not sigma's width
    _disturb_sync(monkeypatch, seed=attempt)
    folder = new_results_folder(config, tmp_path / "res", "run")
    try:
        results = runner.run_campaign(config, folder, report=False,
                                      host=HostSettings.for_command(config))
    except runner.CampaignStopped as stopped:
        # the drives starved of set-points ran into their following-error window, as real ones do:
        # the run stops, non-zero exit, the recording kept, nothing marked good
        status = (folder / "STATUS").read_text()
        log.warning("attempt %d: stopped: %s", attempt, stopped.reason)
        assert "Following error" in stopped.reason and status.startswith("partial: drive fault")
        assert (folder / "data" / "sweep.npz").is_file()
        return
    used = results.trajectories["sweep"]
    slots = used.cycles + used.skipped_slots
    skipped = used.skipped_slots / slots
    assert skipped > 10 * STALL_PROBABILITY ** 2, used     # the disturbance happened
    status = (folder / "STATUS").read_text()
    well = [r for r in results.parameter_rows()
            if r.fitted and r.rel_sigma_percent is not None and r.rel_sigma_percent <= results.rel_sigma_threshold]
    errors = {r.name: r.error_percent for r in well}
    log.warning("attempt %d: %.1f %% of the SYNC slots skipped, %.1f %% of the rows complete, %s; "
                "status %s; errors of the well identified (%%): %s", attempt, 100 * skipped,
                100 * used.valid_fraction, used.rows_left_out, status.splitlines()[0][:80],
                {k: round(v, 2) for k, v in errors.items()})
    if results.quality.passed:
        assert status.startswith("complete")
        assert well and all(abs(e) <= 5.0 for e in errors.values()), errors
    else:
        assert status.startswith("degraded") and results.quality.reasons
