"""Model throughput: regressor + inverse dynamics for 60 s of data at 1 kHz (issue 2).

Target: <= 0.6 s for 60,000 samples, i.e. >= 100 x real time. Prints the measured numbers.
Run: python benchmarks/bench_model.py
"""

import time

import numpy as np

from ident_hw.model import Geometry, InertialParams, ThreePRRR


def main(n=60_000, repeats=5):
    robot = ThreePRRR(Geometry(l1=0.3, l2=0.3, s1=0.15, s2=0.15, h=0.12, a=0.4,
                               gamma=tuple(np.radians([0, 120, 240]))))
    params = InertialParams(603.62, 0.3, 0.00225, 0.5723, 0.0043, 0.2269, 0.0016, f_v=(0.1,) * 6, f_c=(0.2,) * 6)
    t = np.arange(n) / 1000.0
    w = 2 * np.pi * np.array([0.3, 0.5, 0.4, 0.2, 0.25, 0.35])
    amp = np.array([0.05, 0.05, 0.3, 0.04, 0.04, 0.04])
    q, qd, qdd = amp * np.sin(w * t[:, None]), amp * w * np.cos(w * t[:, None]), -amp * w**2 * np.sin(w * t[:, None])
    args = (q[:, :3], qd[:, :3], qdd[:, :3], q[:, 3:], qd[:, 3:], qdd[:, 3:])
    best = {}
    for name, fn in [("regressor", lambda: robot.regressor(*args)),
                     ("inverse_dynamics", lambda: robot.inverse_dynamics(*args, params)),
                     ("regressor_from_actuated (FK + regressor)",
                      lambda: robot.regressor_from_actuated(*robot.actuated_motion(*args), np.zeros(3)))]:
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        best[name] = min(times)
    total = best["regressor"] + best["inverse_dynamics"]
    for name, sec in best.items():
        print(f"{name:45s} {sec * 1e3:8.1f} ms for {n} samples")
    print(f"{'regressor + inverse dynamics':45s} {total * 1e3:8.1f} ms  -> {n / 1000 / total:.0f} x real time "
          f"(target >= 100 x, <= 600 ms)")


if __name__ == "__main__":
    main()
