"""A listener on a ``udp_multicast`` group in a process of its own, so that what it hears is timed by
the kernel however the test process is held up (``SO_TIMESTAMPNS``: each frame's time stamp is
its arrival). Run as ``python bus_listener.py GROUP SECONDS``: prints ``ready``, then after
SECONDS one JSON line ``{"<COB-ID>": [time stamps], ...}`` and, per COB-ID, the data of the
frames (hex) under ``"data <COB-ID>"``."""

import json
import sys
import time

from drivers.bus import BusConfig, open_bus


def main(group: str, seconds: float) -> None:
    bus = open_bus(BusConfig("udp_multicast", group))
    stamps: dict[str, list] = {}
    data: dict[str, list] = {}
    print("ready", flush=True)
    end = time.monotonic() + seconds
    try:
        while (left := end - time.monotonic()) > 0:
            msg = bus.recv(min(left, 0.1))
            if msg is None:
                continue
            key = f"{msg.arbitration_id:#05x}"
            stamps.setdefault(key, []).append(msg.timestamp)
            data.setdefault(f"data {key}", []).append(bytes(msg.data).hex())
    finally:
        bus.shutdown()
    print(json.dumps({**stamps, **data}), flush=True)


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]))
