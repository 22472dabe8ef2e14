"""Simulated EPOS rig: six emulated EPOS2/EPOS4 drives on CANopen in front of a simulated 3PRRR.

::

    from drivers.sim import SimulatedRig
    rig = SimulatedRig.build(robot, true_params, axes,    # robot: a model, axes: (node_id, "epos4", AxisScaling) each
                             interface="virtual", channel="rig", ignore_config=True)
    with rig:
        ...   # a canopen master on the same bus sees six drives

:mod:`drivers.sim.rig` holds the rig (bus, clock, SYNC handling, fault injection),
:mod:`drivers.sim.plant` the simulated 3PRRR, :mod:`drivers.sim.drive` one emulated drive, built
from :mod:`~drivers.sim.objects` (object values), :mod:`~drivers.sim.pdo` (PDOs),
:mod:`~drivers.sim.state_machine` (CiA 402) and :mod:`~drivers.sim.modes` (the demand).
A config's rig is served on a shared bus by ``ident-hw sim CONFIG``.
"""

import lazy_loader

# Each name is imported from its module on first use (PEP 562, by lazy_loader): a master that only
# needs the rig's lockstep SYNC source (drivers.sim.lockstep) does not load the compiled plant.
__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submod_attrs={
    "drive": ["EmulatedDrive"],
    "plant": ["Plant", "PlantJammed", "TruthLog"],
    "rig": ["SimulatedRig"],
})
