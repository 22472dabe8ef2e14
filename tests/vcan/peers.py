"""Programs the vcan tests run as separate processes on the other end of a SocketCAN bus.

Run as ``python peers.py MODE CHANNEL ...``. Each prints ``ready`` on stdout once its socket is
bound (from then on it sees every frame on the bus) and ends when its stdin is closed.

Modes:
    echo CHANNEL
        Answer every frame with one whose id is the received id + 1 (same id format) and whose
        data is the received data reversed.
    record CHANNEL CAN_ID COUNT
        Wait for COUNT frames with id CAN_ID, print their kernel receive timestamps (s, JSON list)
        and exit.
    node CHANNEL NODE_ID PROFILE
        A ``canopen.LocalNode`` serving the project's drive object dictionary
        (:func:`drivers.profiles.make_object_dictionary`), i.e. an SDO server.
"""

import argparse
import json
import sys
import threading

import can

RECV_POLL = 0.1  # s, how often the receive loops look at the stop flag


def _stdin_closed() -> threading.Event:
    closed = threading.Event()

    def wait():
        sys.stdin.read()
        closed.set()

    threading.Thread(target=wait, daemon=True).start()
    return closed


def _ready() -> None:
    print("ready", flush=True)


def echo(channel: str) -> None:
    stop = _stdin_closed()
    with can.Bus(interface="socketcan", channel=channel) as bus:
        _ready()
        while not stop.is_set():
            msg = bus.recv(RECV_POLL)
            if msg is not None:
                bus.send(can.Message(arbitration_id=msg.arbitration_id + 1, is_extended_id=msg.is_extended_id,
                                     data=bytes(reversed(msg.data))))


def record(channel: str, can_id: int, count: int) -> None:
    stop = _stdin_closed()
    stamps = []
    with can.Bus(interface="socketcan", channel=channel,
                 can_filters=[{"can_id": can_id, "can_mask": 0x7FF, "extended": False}]) as bus:
        _ready()
        while len(stamps) < count and not stop.is_set():
            msg = bus.recv(RECV_POLL)
            if msg is not None and msg.arbitration_id == can_id:
                stamps.append(msg.timestamp)
    print(json.dumps(stamps), flush=True)


def node(channel: str, node_id: int, profile: str) -> None:
    import canopen

    from drivers.profiles import make_object_dictionary

    stop = _stdin_closed()
    network = canopen.Network()
    network.connect(interface="socketcan", channel=channel)
    try:
        network.add_node(canopen.LocalNode(node_id, make_object_dictionary(profile, node_id)))
        _ready()
        stop.wait()
    finally:
        network.disconnect()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    modes = parser.add_subparsers(dest="mode", required=True)
    modes.add_parser("echo").add_argument("channel")
    rec = modes.add_parser("record")
    rec.add_argument("channel")
    rec.add_argument("can_id", type=lambda s: int(s, 0))
    rec.add_argument("count", type=int)
    nod = modes.add_parser("node")
    nod.add_argument("channel")
    nod.add_argument("node_id", type=int)
    nod.add_argument("profile")
    args = vars(parser.parse_args())
    {"echo": echo, "record": record, "node": node}[args.pop("mode")](**args)


if __name__ == "__main__":
    main()
