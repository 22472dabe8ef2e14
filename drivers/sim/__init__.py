"""Simulated EPOS rig: six emulated EPOS2/EPOS4 drives on CANopen in front of a simulated 3PRRR.

    from drivers.sim import Plant, SimulatedRig
    rig = SimulatedRig([(1, "epos4", scaling_theta1), ...], Plant(robot, true_params),
                       interface="virtual", channel="rig", ignore_config=True)
    with rig:
        ...   # a canopen master on the same bus sees six drives

Run standalone with ``python -m drivers.sim --interface socketcan --channel vcan0``.
"""

from drivers.sim.drive import EmulatedDrive
from drivers.sim.plant import Plant, TruthSample
from drivers.sim.rig import SimulatedRig

__all__ = ["EmulatedDrive", "Plant", "SimulatedRig", "TruthSample"]
