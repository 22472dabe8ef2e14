"""Model throughput and drift (issue 2).

* Regressor + inverse dynamics for 60 s of data at 1 kHz: target <= 0.6 s for 60,000 samples,
  i.e. >= 100 x real time.
* A 60 s closed-chain simulation (DOP853, PD tracking of a smooth motion): the closure residual
  must stay <= 1e-9 m over the whole run.

Run: python benchmarks/bench_model.py [--speed]   (``--speed``: the throughput only, the machine's
figure of the day that the other benchmarks quote beside theirs)
"""

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import nominal  # noqa: E402
from ident_hw.model import ThreePRRR  # noqa: E402

ROBOT = ThreePRRR(nominal.GEOMETRY)
PARAMS = nominal.TRUE_PARAMS


def main(n=60_000, repeats=5):
    robot, params = ROBOT, PARAMS
    t = np.arange(n) / 1000.0
    w = 2 * np.pi * np.array([0.3, 0.5, 0.4, 0.2, 0.25, 0.35])
    amp = np.array([0.05, 0.05, 0.3, 0.04, 0.04, 0.04])
    q, qd, qdd = amp * np.sin(w * t[:, None]), amp * w * np.cos(w * t[:, None]), -amp * w**2 * np.sin(w * t[:, None])
    args = (q[:, :3], qd[:, :3], qdd[:, :3], q[:, 3:], qd[:, 3:], qdd[:, 3:])
    best = {}

    def from_actuated():
        m = robot.actuated_motion(*args)
        return robot.regressor_from_actuated(m.q, m.qd, m.qdd, np.zeros(3))
    for name, fn in [("regressor", lambda: robot.regressor(*args)),
                     ("inverse_dynamics", lambda: robot.inverse_dynamics(*args, params)),
                     ("regressor_from_actuated (FK + regressor)", from_actuated)]:
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


def simulation_drift(duration=60.0):
    """Max closure residual over a ``duration`` s simulation of PD tracking of a smooth motion."""
    robot, params = ROBOT, PARAMS
    w = 2 * np.pi * np.array([0.3, 0.5, 0.4, 0.2, 0.25, 0.35])
    amp = np.array([0.03, 0.03, 0.2, 0.03, 0.03, 0.03])
    reference = lambda t: (amp * np.sin(w * t), amp * w * np.cos(w * t))  # noqa: E731
    theta0, _ = robot.inverse_kinematics(np.zeros(3), np.zeros(3))
    kp = np.array([2e2, 2e2, 2e2, 2e6, 2e6, 2e6])
    kd = np.array([2e1, 2e1, 2e1, 5e4, 5e4, 5e4])

    def force(t, Theta, Thetad):
        X, Xd = reference(t)
        target = robot.actuated_motion(X[:3], Xd[:3], np.zeros(3), X[3:], Xd[3:], np.zeros(3))
        return kp * (target.q[0] - Theta) + kd * (target.qd[0] - Thetad)

    t = np.linspace(0, duration, int(duration * 100) + 1)
    t0 = time.perf_counter()
    sim = robot.simulate(t, np.r_[theta0[0], 0, 0, 0], np.zeros(6), force, params, np.zeros(3), rtol=1e-8, atol=1e-10)
    elapsed = time.perf_counter() - t0
    residual = robot.closure_residual(sim.X, sim.Theta).max()
    X_ref = reference(t[:, None])[0][:, :3]
    print(f"{duration:.0f} s closed-chain simulation: max closure residual {residual:.1e} m (target <= 1e-9), "
          f"max pose tracking error {np.abs(sim.X - X_ref).max():.1e}, {elapsed:.1f} s wall")


if __name__ == "__main__":
    main()
    if "--speed" not in sys.argv[1:]:
        simulation_drift()
