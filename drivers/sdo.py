"""The master's view of a drive over SDO: canopen's remote node and SDO client, with the response
timeout counted in the time the master was running (:class:`drivers.supervision.WatchClock`).

canopen's client waits for a response with a wall-clock timeout. When the master's own process
is held up (a GIL-holding call, a garbage collection, a busy host) the drive's response comes on
time and waits for the master's notifier, but the wait's timeout has run out meanwhile: after a
hold-up as long as the SDO timeout, the request failed with "No SDO response received" although
the drive had answered (seen during homing, with the lab's 1 s SDO timeout and 1 s hold-ups).
Here a gap in the master's own running counts at most :data:`drivers.supervision.MAX_UNWATCHED`.
"""

from __future__ import annotations

import queue
import struct

import canopen
from canopen.sdo import SdoAbortedError, SdoClient, SdoCommunicationError
from canopen.sdo.constants import RESPONSE_ABORTED

from drivers.supervision import WatchClock

#: s between two looks at the watch clock while waiting for a response
POLL = 0.02


class WatchedSdoClient(SdoClient):
    """canopen's :class:`~canopen.sdo.SdoClient`, its ``RESPONSE_TIMEOUT`` counted in watched time."""

    def read_response(self) -> bytes:
        """The next response (raises canopen's ``SdoAbortedError`` for an abort), or
        ``SdoCommunicationError`` once ``RESPONSE_TIMEOUT`` s of the master's running time
        passed without one."""
        clock = WatchClock()
        start = clock.advance()
        while True:
            try:
                response = self.responses.get(block=True, timeout=min(POLL, self.RESPONSE_TIMEOUT))
                break
            except queue.Empty:
                if clock.advance() - start > self.RESPONSE_TIMEOUT:
                    raise SdoCommunicationError("No SDO response received") from None
        (command,) = struct.unpack_from("B", response)
        if command == RESPONSE_ABORTED:
            (code,) = struct.unpack_from("<L", response, 4)
            raise SdoAbortedError(code)
        return response


class MasterNode(canopen.RemoteNode):
    """canopen's :class:`~canopen.RemoteNode` whose SDO clients are :class:`WatchedSdoClient` s."""

    def add_sdo(self, rx_cobid: int, tx_cobid: int) -> WatchedSdoClient:
        """A :class:`WatchedSdoClient` on the COB-IDs ``rx_cobid``/``tx_cobid``, added to the node's
        SDO channels (canopen's ``add_sdo``, with the watched client)."""
        client = WatchedSdoClient(rx_cobid, tx_cobid, self.object_dictionary)
        self.sdo_channels.append(client)
        if self.has_network():
            self.network.subscribe(client.tx_cobid, client.on_response)
        return client
