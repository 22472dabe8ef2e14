"""Robots from description files (issues 27, 48): the generic model's cost against the hand-made ones.

* regressor per sample (``identification_regressor``: forward kinematics by Newton from the
  previous sample's configuration, passive rates, the tree regressor projected on the
  actuators; compiled, :mod:`ident_hw.model.tree_kernels`) of the generic model read from
  ``configs/robots/*`` against the hand-made 3PRRR and Delta on the same states, in the same
  run, alternated (medians of CPU time), and for the Stewart platform and the 2R arm (issue 48's
  target: at most 2x the hand-made);
* ``plant_dynamics`` per call, and the plant's whole SYNC period (``Plant.step`` at 250 Hz: the
  dynamics and the Runge-Kutta substeps) following a sine (issue 48's target for the Stewart:
  at most 60 µs).

Run: python benchmarks/bench_described.py   (quote ``bench_model.py --speed`` of the same hour)
"""

import sys
import time
from pathlib import Path

import numpy as np

from ident_hw.config import load_config

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import described_hand as dh  # noqa: E402
from ident_hw.config.robots import initial_parameters, model_of

CONFIGS = "configs"
SAMPLES = 2000


def per_call(fn, calls: int, repeats: int = 3) -> float:
    """Best of ``repeats`` of the mean time of ``fn`` over ``calls`` calls, in µs."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, (time.perf_counter() - t0) / calls)
    return best * 1e6


def alternated(fa, fb, calls: int, rounds: int = 9) -> tuple[float, float]:
    """Medians of ``rounds`` alternated timings of ``fa`` and ``fb`` (CPU time of this process,
    each over ``calls`` calls), in µs: A/B in one run on the same inputs, the host's load
    shared by both."""
    a, b = [], []
    for _ in range(rounds):
        for f, out in ((fa, a), (fb, b)):
            t0 = time.process_time()
            f()
            out.append((time.process_time() - t0) / calls)
    return float(np.median(a)) * 1e6, float(np.median(b)) * 1e6


def smooth_motion(home, amplitude, n=SAMPLES, rate=250.0):
    """A multi-sine about ``home`` (n, a) with its rates, sampled at ``rate`` Hz."""
    t = np.arange(n)[:, None] / rate
    w = 2 * np.pi * np.linspace(0.3, 0.9, len(home))
    return home + amplitude * np.sin(w * t), amplitude * w * np.cos(w * t), -amplitude * w**2 * np.sin(w * t)


def hand_and_described(name: str):
    """The hand-made model of ``robot-<name>.yaml`` and the generic one of ``robots/<name>.xml``
    (home from the hand model's kinematics, through the tests' maps of the two trees)."""
    from ident_hw.model.described import DescribedRobot

    hand = model_of(load_config(f"{CONFIGS}/robot-{name}.yaml").robot)
    if name == "3prrr":
        X0 = np.zeros((1, 3))
        theta, beta = hand.inverse_kinematics(X0, X0)
        home = dict(zip(dh.PRRR_JOINTS, dh.prrr_tree(X0, theta, beta, X0)[0]))
        actuated, path = ("theta1", "theta2", "theta3", "zeta1", "zeta2", "zeta3"), dh.PRRR_XML
        amplitude = np.array([0.05, 0.05, 0.05, 0.02, 0.02, 0.02])
    else:
        q0 = np.zeros((1, 3))
        home = dict(zip(dh.DELTA_JOINTS, dh.delta_tree_motion(hand, q0, q0, q0)[0][0]))
        actuated, path = ("q1", "q2", "q3"), dh.DELTA_XML
        amplitude = np.full(3, 0.3)
    return hand, DescribedRobot(path, actuated, home=home), amplitude

def plant_period(robot, params, Theta, Thetad, rate=250.0) -> float:
    """µs per ``Plant.step`` of a period at ``rate`` Hz, the demand following ``Theta``."""
    from drivers.sim.plant import Plant

    plant = Plant(robot, params, Theta[0])
    n = len(robot.actuator_names)
    enabled, limit = np.ones(n, dtype=bool), np.full(n, 1e6)
    demands = [np.array([Theta[k], Thetad[k]]) for k in range(len(Theta))]

    def run():
        for d in demands:
            plant.step(1.0 / rate, d, enabled, limit)
    run()                      # compiled, and the plant settled on the path
    plant = Plant(robot, params, Theta[0])
    return per_call(run, len(demands), repeats=1)


def main():
    print(f"regressor per sample ({SAMPLES} samples of a smooth motion at 250 Hz; the hand-made and the generic "
          "alternated, medians of CPU time) and plant_dynamics per call:")
    for name in ("3prrr", "delta"):
        hand, described, amplitude = hand_and_described(name)
        Theta, Thetad, Thetadd = smooth_motion(hand.home_actuated(), amplitude)
        start = hand.pose(Theta[0], np.zeros(hand.pose_size))
        guess = np.tile(start, (SAMPLES, 1))
        t_hand, t_gen = alternated(lambda: hand.identification_regressor(Theta, Thetad, Thetadd, guess),
                                   lambda: described.identification_regressor(Theta, Thetad, Thetadd, None), SAMPLES)
        pi_hand = initial_parameters(load_config(f"{CONFIGS}/robot-{name}.yaml").robot)
        pi = described.nominal_parameters()
        q = described.pose(Theta[1], None)
        p_hand = per_call(lambda: [hand.plant_dynamics(Theta[1], Thetad[1], pi_hand, start) for _ in range(200)], 200)
        p_gen = per_call(lambda: [described.plant_dynamics(Theta[1], Thetad[1], pi, q) for _ in range(200)], 200)
        print(f"  {name:8s} hand-made {t_hand:8.1f} µs, generic {t_gen:8.1f} µs ({t_gen / t_hand:4.2f}x); "
              f"plant_dynamics hand-made {p_hand:6.1f} µs, generic {p_gen:6.1f} µs")
    for name in ("stewart", "2r"):
        robot = model_of(load_config(f"{CONFIGS}/robot-{name}.yaml").robot)
        amplitude = np.full(len(robot.actuator_names), 0.03 if name == "stewart" else 0.5)
        Theta, Thetad, Thetadd = smooth_motion(robot.home_actuated(), amplitude)
        t_gen = per_call(lambda: robot.identification_regressor(Theta, Thetad, Thetadd, None), SAMPLES)
        pi = robot.nominal_parameters()
        q = robot.pose(Theta[1], None)
        p_gen = per_call(lambda: [robot.plant_dynamics(Theta[1], Thetad[1], pi, q) for _ in range(200)], 200)
        period = plant_period(robot, pi, Theta[:500], Thetad[:500])
        print(f"  {name:8s} generic {t_gen:8.1f} µs; plant_dynamics {p_gen:6.1f} µs; plant per SYNC period "
              f"{period:6.1f} µs")


if __name__ == "__main__":
    main()
