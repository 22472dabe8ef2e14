"""Simulated EPOS rig: six emulated EPOS2/EPOS4 drives on CANopen in front of a simulated 3PRRR.

    from drivers.sim import SimulatedRig
    rig = SimulatedRig.build(geometry, true_params, axes,           # axes: six (node_id, "epos4", AxisScaling)
                             interface="virtual", channel="rig", ignore_config=True)
    with rig:
        ...   # a canopen master on the same bus sees six drives

:mod:`drivers.sim.nominal` holds the project's nominal rig. Run standalone with
``python -m drivers.sim --interface socketcan --channel vcan0``.
"""

from drivers.sim.drive import EmulatedDrive
from drivers.sim.plant import Plant, PlantJammed, TruthLog
from drivers.sim.rig import SimulatedRig

__all__ = ["EmulatedDrive", "Plant", "PlantJammed", "SimulatedRig", "TruthLog"]
