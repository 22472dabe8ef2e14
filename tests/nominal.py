"""The nominal 3PRRR rig of the project (the values of ``configs/robots/3prrr.xml``,
``configs/robot-3prrr.yaml`` and ``configs/sim-3prrr.yaml``, written here independently of them), for the tests and benchmarks that run without a config
(the benchmarks put ``tests/`` on their path to import it).

A config-driven rig is built by the CLI (``ident-hw sim CONFIG``) through
:meth:`drivers.sim.SimulatedRig.build`.
"""

from __future__ import annotations

import math

from drivers.units import AxisScaling
from ident_hw.model import Geometry, InertialParams, ThreePRRR

GEOMETRY = Geometry(l1=0.30, l2=0.30, s1=0.15, s2=0.15, h=0.12, a=0.40,
                    gamma=(0.0, 2 * math.pi / 3, 4 * math.pi / 3))
#: the CAD values (configs/robots/3prrr.xml): slender rods (m l^2 / 12) and a disc (m h^2 / 2), no friction
CAD_PARAMS = InertialParams(m_c=780.0, m_l1=0.30, I_l1=0.30 * 0.30**2 / 12, m_l2=0.354, I_l2=0.354 * 0.30**2 / 12,
                            m_ee=0.78, I_ee=0.78 * 0.12**2 / 2)
#: the paper-identified masses with slender-rod/disc inertias and the simulated friction
TRUE_PARAMS = InertialParams(m_c=603.62, m_l1=0.30, I_l1=0.00225, m_l2=0.5723, I_l2=0.00429225,
                             m_ee=0.2269, I_ee=0.00163368,
                             f_v=(0.02,) * 3 + (40.0,) * 3, f_c=(0.05,) * 3 + (5.0,) * 3)
#: the nominal model (Coulomb smoothing as the configs' ``robot.coulomb_width``)
ROBOT = ThreePRRR(GEOMETRY, coulomb_width=1e-3)
REVOLUTE = AxisScaling("revolute", 2048, 0.0369, gear_ratio=26.0)
PRISMATIC = AxisScaling("prismatic", 2048, 0.0603, screw_lead=0.002)


def axes(profile: str = "epos4", node_ids=(1, 2, 3, 4, 5, 6)) -> list[tuple[int, str, AxisScaling]]:
    """The six drives ``(node_id, profile, AxisScaling)`` in the order theta1..3, zeta1..3."""
    if len(node_ids) != 6:
        raise ValueError(f"six node-IDs needed (theta1..3, zeta1..3), got {list(node_ids)}")
    return [(nid, profile, REVOLUTE if j < 3 else PRISMATIC) for j, nid in enumerate(node_ids)]
