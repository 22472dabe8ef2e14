"""Online estimators: per-sample update cost (3PRRR n = 19, k = 6; Delta base parameters n = 40,
k = 3 on the SVD-DLS paper's training path) and the J_RMSE table of the SVD-DLS / RLS /
damped-RLS comparison of ``tests/test_ident_online.py`` (same stream).

Run from the repository root: ``python benchmarks/bench_ident_online.py``.
"""

import sys
import time
from pathlib import Path

import numpy as np

from ident_hw.identification.online import RLS, SVDDLS, DampedRLS

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from ident_scenarios import PAYLOAD_KG, TRUE, online_scenario  # noqa: E402
from test_ident_online import j_rmse_table, run_all  # noqa: E402

N, K, SAMPLES = 19, 6, 5000
rng = np.random.default_rng(0)
Y = rng.normal(size=(SAMPLES, K, N))
tau = Y @ rng.normal(size=N)
print("update cost, random data, n = 19, k = 6:")
for est in (RLS(N), DampedRLS(N), SVDDLS(N, threshold=1e-6)):
    start = time.perf_counter()
    est.partial_fit(Y, tau)
    per_sample = (time.perf_counter() - start) / SAMPLES
    print(f"  {type(est).__name__:10s} {per_sample * 1e6:7.1f} us/sample  ({1e-3 / per_sample:5.1f} x real time at 1 kHz)")

from ident_hw.model.delta import PARAM_NAMES, Delta, closed_form_base, nominal_parameters  # noqa: E402
from trajectories.delta_paper import training_path  # noqa: E402

delta = Delta()
base = closed_form_base(delta.geometry)
_path = training_path(np.arange(6000) / 100.0)
q, qd, qdd = _path.q, _path.qd, _path.qdd
Yd = delta.regressor(q, qd, qdd)[:, :, [PARAM_NAMES.index(k) for k in base.kept]]
taud = Yd @ (base.H @ nominal_parameters()) + rng.normal(0, 0.01, size=(len(Yd), 3))   # N·m
scale = np.maximum(np.abs(base.H @ nominal_parameters()), 1e-2)
print("update cost, Delta base parameters, n = 40, k = 3, training path at 100 Hz, torque noise 0.01 N·m "
      "(first 10 s not timed):")
std = np.full(3, 0.01)
for est in (RLS(40, 0.998, scale=scale, output_std=std), DampedRLS(40, 0.998, scale=scale, output_std=std),
            SVDDLS(40, 0.998, scale=scale, output_std=std)):
    est.partial_fit(Yd[:1000], taud[:1000])
    start = time.perf_counter()
    est.partial_fit(Yd[1000:], taud[1000:])
    per_sample = (time.perf_counter() - start) / (len(Yd) - 1000)
    print(f"  {type(est).__name__:10s} {per_sample * 1e6:7.1f} us/sample  (rank {getattr(est, 'rank_', 40)})")

sc = online_scenario()
traces = run_all(sc)
names = ("rich 20 s", "slow circle 20 s", f"rich + {PAYLOAD_KG} kg 20 s")
print("\nJ_RMSE of the a-priori force predictions (N and N·m mixed, the SVD-DLS paper eq. 87), lambda = 0.998 at 200 Hz:")
print(f"  {'method':10s}" + "".join(f"{n:>22s}" for n in names) + f"{'cov. growth in circle':>24s}{'m_ee 5 % after':>16s}")
i_ee = sc.names.index("m_ee")
target = TRUE.m_ee + PAYLOAD_KG
a_end, b_end = np.flatnonzero(sc.phase == 0)[-1], np.flatnonzero(sc.phase == 1)[-1]
c = sc.phase == 2
for name, j in j_rmse_table(sc, traces).items():
    tr = traces[name]
    outside = np.flatnonzero(np.abs(tr.coef[c, i_ee] / target - 1) >= 0.05)
    settle = (sc.t[c][outside[-1] + 1] - sc.t[c][0]) if outside.size else 0.0
    growth = tr.covariance_trace[b_end] / tr.covariance_trace[a_end]
    print(f"  {name:10s}" + "".join(f"{v:22.4g}" for v in j) + f"{growth:23.3g}x{settle:15.2f}s")
