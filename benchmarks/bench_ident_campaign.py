"""Whole offline identification of the paper's campaign at 1 kHz, target <= 5 s.

Campaign (``trajectories`` package, nominal limits, 0.5 s dwell at every waypoint): carriage
sweep, five squares, validation triangle, about 60 s of data at 1 kHz. Measurements made with
the model and the truth of the tests (``tests/ident_scenarios.py``): positions in encoder
counts, currents with 3 % Gaussian noise rounded to 1 mA. Timed: filtering and
differentiation, forward kinematics and regressor, parallel filtering and decimation, the two
SQP steps (each cross-checked by lsq_linear) with WLS statistics, the base-parameter analysis
and the validation on the triangle. Not timed: making the trajectories and the measurements.

Run from the repository root: ``python benchmarks/bench_ident_campaign.py``.
"""

import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from ident_hw.identification import base_parameters, validation_metrics, wls
from ident_hw.filtering import FilterSettings

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from ident_scenarios import (CAD, FORCE_PER_AMP, HELD_KNOWN, NAMES, PAPER_STEPS, ROBOT, TRUE,  # noqa: E402
                             exact_regressor, identify_paper_steps, measure, paper_campaign)
from measured_dataset import build_dataset  # noqa: E402

RATE = 1000.0
truth = TRUE.as_vector()
campaign = paper_campaign(rate=RATE, dwell=0.5)
rng = np.random.default_rng(0)
recordings = {}
for name, tr in campaign.items():
    Theta, current = measure(SimpleNamespace(Theta=tr.Theta, tau=exact_regressor(tr) @ truth), rng)
    recordings[name] = (tr.t, Theta, current)
total = sum(tr.duration for tr in campaign.values())
samples = sum(len(tr.t) for tr in campaign.values())
print(f"campaign: {len(campaign)} trajectories, {total:.1f} s, {samples} samples at {RATE:g} Hz")

timings = {}
start = time.perf_counter()
settings = FilterSettings.for_sample_rate(RATE, bandwidth_hz=5.0)
data = {name: build_dataset(ROBOT, t, Theta, current, FORCE_PER_AMP, np.zeros(3), settings)
        for name, (t, Theta, current) in recordings.items()}
timings["preparation (filter, FK, regressor, decimation)"] = time.perf_counter() - start
t1 = time.perf_counter()
initial = CAD.as_vector()
initial[NAMES.index(HELD_KNOWN)] = truth[NAMES.index(HELD_KNOWN)]
fits = identify_paper_steps({n: (d.Y, d.tau) for n, d in data.items()}, initial)
sigma = np.full(len(NAMES), np.nan)
for (_, names, free), fit in zip(PAPER_STEPS, fits):
    Y = np.concatenate([data[n].Y for n in names])
    tau = np.concatenate([data[n].tau for n in names])
    idx = [NAMES.index(p) for p in free]
    held = [i for i in range(len(NAMES)) if i not in idx]
    sigma[idx] = wls(Y[:, :, idx], tau - Y[:, :, held] @ fit.coef[held], free, output_std=fit.output_std).std
timings["SQP steps + lsq_linear + WLS statistics"] = time.perf_counter() - t1
t2 = time.perf_counter()
base = base_parameters(np.concatenate([d.Y for n, d in data.items() if n != "triangle"]), NAMES, scale=initial)
tri = data["triangle"]
metrics = validation_metrics(tri.tau, tri.Y @ fits[-1].coef)
with_truth = validation_metrics(tri.tau, tri.Y @ truth)  # the noise floor of the measured forces
timings["base parameters + validation"] = time.perf_counter() - t2
elapsed = time.perf_counter() - start

for what, seconds in timings.items():
    print(f"  {what:50s} {seconds:6.2f} s")
print(f"  {'total (target <= 5 s)':50s} {elapsed:6.2f} s")
coef = fits[-1].coef
print(f"\n{HELD_KNOWN} held at its known value; filter {settings.cutoff_hz:g} Hz, decimation {settings.decimation}")
print(f"{'parameter':12s}{'truth':>12s}{'identified':>12s}{'sigma':>11s}{'error/sigma':>13s}")
for i, name in enumerate(NAMES):
    if name == HELD_KNOWN:
        continue
    print(f"{name:12s}{truth[i]:12.5g}{coef[i]:12.5g}{sigma[i]:11.2g}{(coef[i] - truth[i]) / sigma[i]:13.2f}")
print(f"\nbase-parameter rank of sweep + squares: {base.rank} of {len(NAMES)}")
for label, m in (("identified", metrics), ("true (noise floor)", with_truth)):
    print(f"triangle (held out), {label:18s} parameters: d_tau {m.d_tau_percent:6.2f} %, J_RMSE {m.j_rmse:.3g}, "
          f"NRMS % {np.round(m.nrms_percent, 2).tolist()}")
