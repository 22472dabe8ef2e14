"""Optimise a described robot's joint excitation once and write it where its config reads it.

    python -m ident_hw.experiment.excitation CONFIG TRAJECTORY OUT.json [--iterations N]

optimises the sines of the config's ``joint_excitation`` named TRAJECTORY (its duration,
bandwidth, harmonics, seed, fade and amplitude, the robot's actuator limits and
``robot.described.max_condition``) for the scaled condition of the numerical base regressor
(:func:`trajectories.joint_optimisation.optimise_joint_excitation`) and writes them to OUT.json;
the trajectory then reads them with ``path: OUT.json`` (relative to the config). The file, not
the optimisation, is what a run uses: the same trajectory on every host.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from trajectories.joint_optimisation import optimise_joint_excitation
from trajectories.joint_space import JointHarmonics

from ident_hw.config import load_config
from ident_hw.config.file import Config
from ident_hw.config.robots import kind_of, model_of

from .robot_trajectories import actuator_limits, excitation_bandwidth


def optimised_sines(config: Config, name: str, max_iter: int = 30, samples: int = 150) -> JointHarmonics:
    """The optimised sines of the config's ``joint_excitation`` ``name``.

    Raises:
        ValueError: no such trajectory, or not a joint excitation of a described robot, naming it.
    """
    tcfg = next((t for t in config.trajectories if t.name == name), None)
    if tcfg is None or tcfg.kind != "joint_excitation" or tcfg.kind not in kind_of(config.robot).trajectory_kinds:
        raise ValueError(f"{config.source}: trajectories: no joint_excitation named {name!r} of a described robot")
    if tcfg.duration is None:
        raise ValueError(f"{config.source}: trajectories: {name!r}: a joint_excitation needs its duration")
    robot = model_of(config.robot)
    return optimise_joint_excitation(robot, actuator_limits(config.robot), tcfg.duration,
                                     excitation_bandwidth(tcfg, config.identification.filter.bandwidth
                                                          if config.identification else 2.0), tcfg.harmonics, fade=tcfg.fade,
                                     seed=tcfg.seed, amplitude=tcfg.amplitude,
                                     max_condition=config.robot.described_settings.max_condition,
                                     max_iter=max_iter, samples=samples)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m ident_hw.experiment.excitation",
                                     description="optimise a described robot's joint excitation, write its sines")
    parser.add_argument("config")
    parser.add_argument("trajectory", help="the name of a joint_excitation of the config")
    parser.add_argument("out", type=Path, help="the JSON file the trajectory's path then names")
    parser.add_argument("--iterations", type=int, default=30, help="L-BFGS-B iterations (default 30)")
    args = parser.parse_args(argv)
    sines = optimised_sines(load_config(args.config), args.trajectory, max_iter=args.iterations)
    out = args.out
    sines.save(out)
    iterations = sines.optimised_for.iterations if sines.optimised_for else None   # set by the optimiser
    print(f"{out}: scaled condition of the base regressor {sines.cond_initial:.4g} drawn, "
          f"{sines.cond_final:.4g} optimised ({iterations} iterations)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
