"""Interface-local IPv6 multicast groups for the tests on python-can's ``udp_multicast`` bus:
each test a group of its own (parallel runs do not meet), and whether this host loops multicast
back to its own sockets at all."""

import secrets
import socket


def interface_local_group() -> str:
    """A fresh interface-local IPv6 multicast group (scope 1), so that parallel runs do not meet."""
    return f"ff11::4944:{secrets.randbits(16):x}:{secrets.randbits(16):x}"


def loopback_multicast_works(group: str) -> bool:
    """Whether a frame sent on ``group`` reaches another socket of this host."""
    if not socket.has_ipv6:
        return False
    import can

    from drivers.bus import BusConfig, open_bus
    try:
        with open_bus(BusConfig("udp_multicast", group)) as a, open_bus(BusConfig("udp_multicast", group)) as b:
            a.send(can.Message(arbitration_id=0x7FF, data=b"", is_extended_id=False))
            return b.recv(2.0) is not None
    except (OSError, can.CanError):
        return False
