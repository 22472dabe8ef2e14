"""Exceptions of the drive layer.

Every error names the node (node-ID and axis name) it concerns, so that a message read in a log
is enough to find the drive. :class:`DriveFault` and its subclasses are raised by the master after
the motion has been stopped and the drives disabled; ``recording`` then holds the path of the
samples saved up to the fault (or ``None`` when nothing was being recorded).
"""

from __future__ import annotations

import os


class DriveError(Exception):
    """Base class of the errors raised by :mod:`drivers`."""


class ConfigError(DriveError, ValueError):
    """A configuration value is invalid (the message names the key or axis)."""


class BusOpenError(ConfigError):
    """The CAN bus could not be opened (no such interface or channel, adapter absent, no driver)."""


class RecordingError(DriveError, ValueError):
    """A recording cannot be used: unreadable, truncated beyond repair, or not made with the
    axes it is read with (the message names the file)."""


class BusLoadError(ConfigError):
    """The PDO traffic of a run does not fit the bitrate of the bus."""


class NodeError(DriveError):
    """A node did not do what it was asked (SDO abort or timeout, state change refused)."""

    def __init__(self, node: str, message: str):
        super().__init__(f"{node}: {message}")
        self.node = node


class BringUpError(NodeError):
    """A node could not be brought up (absent, wrong identity, refused configuration)."""


class DriveFault(DriveError):
    """A fault that stopped the motion.

    Args:
        node: ``"node 3 (theta1)"``-style name of the drive, or ``"bus"``.
        code: the CANopen/maxon error code (EMCY, 0x603F or 0x1003:01) when there is one.
        text: readable description.
    """

    def __init__(self, node: str, code: int | None, text: str):
        code_text = f" [0x{code:04X}]" if code is not None else ""
        super().__init__(f"{node}: {text}{code_text}")
        self.node = node
        self.code = code
        self.text = text
        self.recording: str | os.PathLike | None = None  # path of the samples saved before the fault, set by the stream


class HeartbeatTimeout(DriveFault):
    """A node's heartbeat was not received within the consumer timeout."""


class BusError(DriveFault):
    """The CAN bus reported an error (error frame, bus-off, failed send)."""

    def __init__(self, text: str):
        super().__init__("bus", None, text)
