"""Serve a simulated rig on a CAN bus until SIGINT/SIGTERM.

    python -m drivers.sim --interface socketcan --channel vcan0 [--profile epos4] [--sync-period 0.004]
                          [--lockstep]

Uses the nominal 3PRRR of :mod:`drivers.sim.nominal`; a config-driven rig is the CLI's
``ident-hw sim CONFIG`` (:meth:`SimulatedRig.build`).
"""

from __future__ import annotations

import argparse
import signal
import threading

from drivers.sim import SimulatedRig, nominal
from drivers.sim.plant import DEFAULT_MAX_SUBSTEP


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(prog="python -m drivers.sim", description=__doc__.splitlines()[0])
    parser.add_argument("--interface", default="virtual", help="python-can interface (virtual, socketcan, ...)")
    parser.add_argument("--channel", default="vcan0")
    parser.add_argument("--bitrate", type=int, default=None)
    parser.add_argument("--profile", choices=("epos2", "epos4"), default="epos4")
    parser.add_argument("--node-ids", type=int, nargs=6, default=[1, 2, 3, 4, 5, 6], metavar="ID")
    parser.add_argument("--sync-period", type=float, default=None,
                        help="plant step per SYNC in s (default: the EPOS4's 0x60C2 or the measured SYNC interval)")
    parser.add_argument("--lockstep", action="store_true",
                        help="answer each SYNC as one step of --sync-period, never by the clock (a master "
                             "with bus.sync: lockstep)")
    parser.add_argument("--current-noise-ma", type=float, default=2.0)
    parser.add_argument("--max-substep", type=float, default=DEFAULT_MAX_SUBSTEP,
                        help="integration step of the plant in s (a slow host may need a coarser one)")
    args = parser.parse_args(argv)
    if args.lockstep and not args.sync_period:
        parser.error("--lockstep needs --sync-period")
    bus_kwargs = {"interface": args.interface, "channel": args.channel}
    if args.bitrate:
        bus_kwargs["bitrate"] = args.bitrate
    rig = SimulatedRig.build(nominal.ROBOT, nominal.TRUE_PARAMS, nominal.axes(args.profile, args.node_ids),
                             max_substep=args.max_substep, lockstep=args.lockstep,
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
