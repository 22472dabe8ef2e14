"""Simulated EPOS rig: six emulated EPOS2/EPOS4 drives on CANopen in front of a simulated 3PRRR.

    from drivers.sim import SimulatedRig
    rig = SimulatedRig.build(robot, true_params, axes,    # robot: a model, axes: (node_id, "epos4", AxisScaling) each
                             interface="virtual", channel="rig", ignore_config=True)
    with rig:
        ...   # a canopen master on the same bus sees six drives

:mod:`drivers.sim.rig` holds the rig (bus, clock, SYNC handling, fault injection),
:mod:`drivers.sim.plant` the simulated 3PRRR, :mod:`drivers.sim.drive` one emulated drive, built
from :mod:`~drivers.sim.objects` (object values), :mod:`~drivers.sim.pdo` (PDOs),
:mod:`~drivers.sim.state_machine` (CiA 402) and :mod:`~drivers.sim.modes` (the demand);
:mod:`drivers.sim.nominal` holds the project's nominal rig (for tests and benchmarks that run
without a config). A config's rig is served on a shared bus by ``ident-hw sim CONFIG``.
"""

from drivers.sim.drive import EmulatedDrive
from drivers.sim.plant import Plant, PlantJammed, TruthLog
from drivers.sim.rig import SimulatedRig

__all__ = ["EmulatedDrive", "Plant", "PlantJammed", "SimulatedRig", "TruthLog"]
