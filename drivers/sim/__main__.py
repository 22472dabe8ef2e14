"""Serve a simulated rig on a CAN bus until SIGINT/SIGTERM.

    python -m drivers.sim --interface socketcan --channel vcan0 [--profile epos4] [--sync-period 0.004]

Uses the nominal 3PRRR (geometry, drive data and the paper-identified masses); a config-driven
rig is the CLI's ``ident-hw sim CONFIG``.
"""

from __future__ import annotations

import argparse
import math
import signal
import threading

from drivers.sim import Plant, SimulatedRig
from drivers.units import AxisScaling
from ident_hw.model import Geometry, InertialParams, ThreePRRR

NOMINAL_GEOMETRY = Geometry(l1=0.30, l2=0.30, s1=0.15, s2=0.15, h=0.12, a=0.40,
                            gamma=(0.0, 2 * math.pi / 3, 4 * math.pi / 3))
NOMINAL_TRUE_PARAMS = InertialParams(m_c=603.62, m_l1=0.30, I_l1=0.00225, m_l2=0.5723,
                                     I_l2=0.5723 * 0.30**2 / 12, m_ee=0.2269, I_ee=0.2269 * 0.12**2 / 2)
REVOLUTE = AxisScaling("revolute", 2048, 0.0369, gear_ratio=26.0)
PRISMATIC = AxisScaling("prismatic", 2048, 0.0603, screw_lead=0.002)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(prog="python -m drivers.sim", description=__doc__.splitlines()[0])
    parser.add_argument("--interface", default="virtual", help="python-can interface (virtual, socketcan, ...)")
    parser.add_argument("--channel", default="vcan0")
    parser.add_argument("--bitrate", type=int, default=None)
    parser.add_argument("--profile", choices=("epos2", "epos4"), default="epos4")
    parser.add_argument("--node-ids", type=int, nargs=6, default=[1, 2, 3, 4, 5, 6], metavar="ID")
    parser.add_argument("--sync-period", type=float, default=None,
                        help="plant step per SYNC in s (default: 0x1006 or the measured SYNC interval)")
    parser.add_argument("--current-noise-ma", type=float, default=2.0)
    args = parser.parse_args(argv)
    bus_kwargs = {"interface": args.interface, "channel": args.channel}
    if args.bitrate:
        bus_kwargs["bitrate"] = args.bitrate
    nodes = [(nid, args.profile, REVOLUTE if j < 3 else PRISMATIC) for j, nid in enumerate(args.node_ids)]
    rig = SimulatedRig(nodes, Plant(ThreePRRR(NOMINAL_GEOMETRY), NOMINAL_TRUE_PARAMS),
                       sync_period=args.sync_period, current_noise_ma=args.current_noise_ma, **bus_kwargs)
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    with rig:
        print(f"simulated rig: {args.profile} nodes {args.node_ids} on {args.interface}:{args.channel}; Ctrl-C stops",
              flush=True)
        while not done.wait(0.5):
            pass


if __name__ == "__main__":
    main()
