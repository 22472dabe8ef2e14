"""CANopen drivers for Maxon EPOS2/EPOS4 drives, bus set-up and the simulated EPOS rig.

The master side (everything outside :mod:`drivers.sim`) never imports :mod:`ident_hw`.
"""
