"""Per-sample update cost of the online estimators (n = 19 parameters, k = 6 outputs)."""

import time

import numpy as np

from ident_hw.identification.online import RLS, SVDDLS, DampedRLS

N, K, SAMPLES = 19, 6, 5000
rng = np.random.default_rng(0)
Y = rng.normal(size=(SAMPLES, K, N))
tau = Y @ rng.normal(size=N)
for est in (RLS(N), DampedRLS(N), SVDDLS(N)):
    start = time.perf_counter()
    est.partial_fit(Y, tau)
    per_sample = (time.perf_counter() - start) / SAMPLES
    print(f"{type(est).__name__:10s} {per_sample * 1e6:7.1f} us/sample  ({1e-3 / per_sample:5.1f} x real time at 1 kHz)")
