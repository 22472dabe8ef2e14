"""Programs the vcan tests run as separate processes on the other end of a SocketCAN bus.

Run as ``python peers.py MODE CHANNEL ...``. Each prints ``ready`` on stdout once its socket is
bound (from then on it sees every frame on the bus); they run until SIGTERM unless told otherwise.

Modes:
    echo CHANNEL
        Answer every frame with one whose id is the received id + 1 (same id format) and whose
        data is the received data reversed.
    record CHANNEL CAN_ID COUNT
        Wait for COUNT frames with the 11-bit id CAN_ID, print their kernel receive timestamps
        (s, JSON list) and exit.
"""

import argparse
import json

import can


def echo(channel: str) -> None:
    with can.Bus(interface="socketcan", channel=channel) as bus:
        print("ready", flush=True)
        for msg in bus:
            bus.send(can.Message(arbitration_id=msg.arbitration_id + 1, is_extended_id=msg.is_extended_id,
                                 data=bytes(reversed(msg.data))))


def record(channel: str, can_id: int, count: int) -> None:
    stamps = []
    with can.Bus(interface="socketcan", channel=channel,
                 can_filters=[{"can_id": can_id, "can_mask": 0x7FF, "extended": False}]) as bus:
        print("ready", flush=True)
        for msg in bus:
            stamps.append(msg.timestamp)
            if len(stamps) == count:
                break
    print(json.dumps(stamps), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    modes = parser.add_subparsers(dest="mode", required=True)
    modes.add_parser("echo").add_argument("channel")
    rec = modes.add_parser("record")
    rec.add_argument("channel")
    rec.add_argument("can_id", type=lambda s: int(s, 0))
    rec.add_argument("count", type=int)
    args = vars(parser.parse_args())
    {"echo": echo, "record": record}[args.pop("mode")](**args)


if __name__ == "__main__":
    main()
