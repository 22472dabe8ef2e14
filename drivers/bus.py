"""Opening the CAN bus and the CANopen network, and the bus-load budget of a run.

Everything else in :mod:`drivers` receives a :class:`canopen.Network`; nothing below this module
knows which python-can interface is underneath (``socketcan`` on ``vcan0``/``can0``, any other
adapter, or the in-process ``virtual`` bus).
"""

from __future__ import annotations

import errno
import importlib
import ipaddress
import logging
import math
import os
import queue
import socket
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping

import can
import can.interfaces.virtual
import canopen

from drivers.errors import BusLoadError, BusOpenError, ConfigError


logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class BusConfig:
    """Plain settings of one CAN bus.

    Args:
        interface: python-can interface name (``"socketcan"``, ``"virtual"``, ``"pcan"``, ...).
        channel: interface channel (``"vcan0"``, ``"can0"``, a virtual channel name, ...).
        bitrate: nominal bitrate in bit/s; ``None`` for a bus without one (``virtual``, or an
            interface configured outside Python) — the bus-load check is then skipped.
        receive_own_messages: deliver the frames this process sends back to its own listeners.
            The acquisition needs it (the SYNC frames are the cycle boundaries and the RPDO
            echoes are the recorded targets); SocketCAN loops back frames sent by the kernel BCM
            regardless.
        ignore_config: ignore the user's python-can configuration files and environment
            (tests set it so that nothing leaks in).
        options: further keyword arguments for :class:`can.Bus`.
    """

    interface: str
    channel: str | int
    bitrate: int | None = None
    receive_own_messages: bool = True
    ignore_config: bool = False
    options: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def from_mapping(cls, settings: Mapping[str, Any], where: str = "bus") -> "BusConfig":
        """Build from a plain mapping (e.g. a YAML section); unknown keys go to ``options``."""
        settings = dict(settings)
        for key in ("interface", "channel"):
            if key not in settings:
                raise ConfigError(f"{where}: missing key {key!r}")
        known = {k: settings.pop(k) for k in
                 ("interface", "channel", "bitrate", "receive_own_messages", "ignore_config")
                 if k in settings}
        bitrate = known.get("bitrate")
        if bitrate is not None and (not isinstance(bitrate, int) or bitrate <= 0):
            raise ConfigError(f"{where}.bitrate: a positive integer in bit/s, got {bitrate!r}")
        return cls(**known, options=settings)


class VirtualBus(can.interfaces.virtual.VirtualBus):
    """python-can's in-process ``virtual`` bus, delivering each frame without ``copy.deepcopy``
    and its own echo first.

    python-can's :meth:`can.interfaces.virtual.VirtualBus.send` deep-copies the message once per
    receiver, which is most of the cost of a frame (a lockstep cycle of six drives carries about
    twenty). Here each receiver gets a new :class:`can.Message` built from the sent one's fields,
    the same content the deep copy gives.

    The echo (``receive_own_messages``) is queued before the frame reaches any other bus, as a
    CAN controller loops back its frame before any node can answer it: python-can puts it in the
    order the buses were opened, so a receiver opened earlier (the simulated rig's thread) could
    answer a SYNC before the sender saw its own SYNC, and the answer would fall into the cycle
    before. It shares python-can's channels, so it talks to any other ``virtual`` bus of the
    process.

    Unbounded (``rx_queue_size`` 0, the default), its receive queue is a ``queue.SimpleQueue``
    (written in C) instead of python-can's ``queue.Queue``, whose lock and two conditions
    in Python cost every frame twice (put and get): the simulated rig in lockstep carries some
    ten frames a cycle.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        if self.queue.maxsize == 0:
            with can.interfaces.virtual.channels_lock:
                # python-can declares its channels' queues as queue.Queue; they are only put to and got from
                fast: Any = queue.SimpleQueue()
                self.channel[self.channel.index(self.queue)] = fast
                self.queue = fast

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """:meth:`can.BusABC.recv` without its per-frame filter test and debug log where no
        filter is set (every frame passes): the next frame, or None after ``timeout`` s."""
        if self._filters is not None or not self._open:
            return super().recv(timeout)
        try:
            return self.queue.get(True, timeout)
        except queue.Empty:
            return None

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """A new :class:`can.Message` with ``msg``'s fields to this bus's own queue first (with
        ``receive_own_messages``: the echo), then to every other bus of the channel, stamped with
        the time it was sent unless ``preserve_timestamps``; :class:`can.CanOperationError` when a
        receive queue stayed full for ``timeout`` s."""
        self._check_if_open()
        timestamp = msg.timestamp if self.preserve_timestamps else time.time()
        data = bytes(msg.data)
        receivers = [q for q in self.channel if q is not self.queue]
        if self.receive_own_messages:
            receivers.insert(0, self.queue)
        all_sent = True
        for bus_queue in receivers:
            copy = can.Message(timestamp=timestamp, arbitration_id=msg.arbitration_id,
                               is_extended_id=msg.is_extended_id, is_remote_frame=msg.is_remote_frame,
                               is_error_frame=msg.is_error_frame, channel=self.channel_id, dlc=msg.dlc,
                               data=bytearray(data), is_fd=msg.is_fd, is_rx=bus_queue is not self.queue,
                               bitrate_switch=msg.bitrate_switch,
                               error_state_indicator=msg.error_state_indicator)
            try:
                bus_queue.put(copy, block=True, timeout=timeout)
            except queue.Full:
                all_sent = False
        if not all_sent:
            raise can.CanOperationError("Could not send message to one or more recipients")

    def send_data(self, arbitration_id: int, data: bytes) -> None:
        """:meth:`send` of a standard (11-bit) data frame given by its COB-ID and data, each
        receiver's copy built at once, without a message for the sender first: what
        :class:`FrameSending` networks send through (a lockstep cycle of the simulated rig carries
        some twenty frames). A full bounded receive queue blocks, as :meth:`send` without a time-out."""
        self._check_if_open()
        timestamp = 0.0 if self.preserve_timestamps else time.time()   # a new message's time stamp is 0
        data = bytes(data)
        own, channel = self.queue, self.channel_id
        if self.receive_own_messages:
            own.put(can.Message(timestamp=timestamp, arbitration_id=arbitration_id, is_extended_id=False,
                                channel=channel, dlc=len(data), data=bytearray(data), is_rx=False))
        for bus_queue in self.channel:
            if bus_queue is not own:
                bus_queue.put(can.Message(timestamp=timestamp, arbitration_id=arbitration_id, is_extended_id=False,
                                          channel=channel, dlc=len(data), data=bytearray(data)))


def is_local(interface: str, channel: str | int) -> bool:
    """True for a bus that cannot reach hardware, where only a simulated rig can answer:
    python-can ``virtual``, a SocketCAN ``vcan*``, or ``udp_multicast`` on an interface-local
    IPv6 group (scope 1, ``ff01::/16`` and ``ffX1``: RFC 4291, loopback only, no datagram leaves
    the host; python-can's default groups are site-wide and are not)."""
    channel = str(channel)
    if interface == "udp_multicast":
        try:
            group = ipaddress.ip_address(channel)
        except ValueError:
            return False
        return group.version == 6 and group.is_multicast and group.packed[1] & 0x0F == 1
    return interface == "virtual" or (interface == "socketcan" and channel.startswith("vcan"))


def has_own_timer(interface: str) -> bool:
    """python-can's ``interface`` sends periodic frames from a timer of its own (the kernel's BCM on
    SocketCAN, an adapter's hardware), not from a Python thread: its bus class has its own
    ``_send_periodic_internal``. An interface python-can does not know has none."""
    try:
        module, name = can.interfaces.BACKENDS[interface]
        bus_class = getattr(importlib.import_module(module), name)
    except (KeyError, ImportError, AttributeError):
        return False
    return bus_class._send_periodic_internal is not can.BusABC._send_periodic_internal


def open_bus(config: BusConfig) -> can.BusABC:
    """Open the python-can bus described by ``config`` (``virtual``: :class:`VirtualBus`)."""
    kwargs = dict(config.options)
    if config.bitrate is not None and config.interface != "virtual":
        kwargs["bitrate"] = config.bitrate
    try:
        if config.interface == "virtual":
            return VirtualBus(channel=config.channel, receive_own_messages=config.receive_own_messages,
                              **kwargs)
        # udp_multicast refuses receive_own_messages, yet the kernel's multicast loopback (on
        # by default) hands every datagram a socket sends back to it, in sending order
        own: dict[str, Any] = ({} if config.interface == "udp_multicast"
                               else {"receive_own_messages": config.receive_own_messages})
        bus = can.Bus(interface=config.interface, channel=config.channel, **own,
                      ignore_config=config.ignore_config, **kwargs)
        if config.interface == "udp_multicast":
            only_its_own_group(bus)
        return bus
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        raise BusOpenError(
            f"cannot open CAN bus interface={config.interface!r} channel={config.channel!r}: {exc}"
            + _socketcan_hint(config, exc)) from exc


#: Linux's ``IPV6_MULTICAST_ALL`` and ``IP_MULTICAST_ALL`` (Python's socket module has no names
#: for them): level and option number by address family
_MULTICAST_ALL = {socket.AF_INET6: (socket.IPPROTO_IPV6, 29), socket.AF_INET: (socket.IPPROTO_IP, 49)}


def only_its_own_group(bus: can.BusABC) -> None:
    """A ``udp_multicast`` bus hears its own group only. Linux hands a socket bound to a port the
    datagrams of *every* group any socket of the host joined on that port (``IPV6_MULTICAST_ALL``,
    on by default): python-can's buses all bind its one default port, so two rigs on two groups
    of one host, or two test runs, would hear each other. The option is switched off on the
    bus's socket (Linux 4.20 and later; elsewhere nothing changes)."""
    if not sys.platform.startswith("linux"):
        return
    try:
        with socket.socket(fileno=os.dup(bus.fileno())) as sock:
            level, option = _MULTICAST_ALL[sock.family]
            sock.setsockopt(level, option, 0)
    except (OSError, KeyError, NotImplementedError, ValueError) as exc:
        logger.debug("udp_multicast: hears every group of its port (%s)", exc)


def _socketcan_hint(config: BusConfig, exc: BaseException) -> str:
    """What a SocketCAN error number means on the rig's PC, in words (empty for anything else)."""
    if config.interface != "socketcan":
        return ""
    code = getattr(exc, "errno", None) or getattr(exc.__context__, "errno", None)
    if code == errno.EAFNOSUPPORT:
        return " (this kernel has no SocketCAN: load its modules, `sudo modprobe can_raw`, or use another interface)"
    if code == errno.ENODEV:
        return (f" (no network interface {config.channel!r}: `ip link show` lists them; a USB adapter's appears "
                f"when plugged in, then `sudo ip link set {config.channel} up type can bitrate …`)")
    return ""


#: s between a canopen notifier thread's checks for a stop request: canopen's default (1 s) makes
#: every disconnect wait up to a second on an idle bus
NOTIFIER_CYCLE = 0.1


class FrameSending(canopen.Network):
    """A :class:`canopen.Network` whose standard data frames on a :class:`VirtualBus` go out
    through :meth:`VirtualBus.send_data` (the same frames, without canopen's message made only to
    be copied); any other frame or bus as canopen sends it."""

    def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None:
        bus = self.bus
        if remote or can_id > 0x7FF or type(bus) is not VirtualBus:
            return super().send_message(can_id, data, remote)
        with self.send_lock:
            bus.send_data(can_id, data)
        self.check()


class BusNetwork(FrameSending):
    """A :class:`canopen.Network` that keeps the :class:`BusConfig` it was opened from.

    The bus settings (bitrate for the bus-load budget, interface) then have one source: the
    drive layer reads them from ``network.config`` instead of taking them a second time.
    """

    NOTIFIER_CYCLE = NOTIFIER_CYCLE

    def __init__(self, bus: can.BusABC, config: BusConfig):
        super().__init__(bus)
        self.config = config

    @property
    def timer_periodic(self) -> bool:
        """The bus sends periodic frames from a timer outside the master's process: the kernel
        BCM on SocketCAN, an adapter's hardware, or a timing process
        (:class:`drivers.timing.TimedBus`), not from a thread of this process."""
        if self.bus is None:      # not open: no timer at all
            return False
        return (getattr(self.bus, "own_timer", False)
                or type(self.bus)._send_periodic_internal is not can.BusABC._send_periodic_internal)

    @property
    def timing(self) -> str:
        """Where the periodic frames come from, in words (for the recordings' metadata)."""
        return getattr(self.bus, "description", None) or (
            "the bus's own timer" if self.timer_periodic else "a thread of the master's process")

    def alive(self) -> None:
        """The master's own loop made progress (its supervision calls this at every check): a
        timing process (:meth:`drivers.timing.TimedBus.alive`) watches it; else nothing."""
        alive = getattr(self.bus, "alive", None)
        if alive is not None:
            alive()

    def send_periodic(self, can_id: int, data: bytes, period: float, remote: bool = False):
        """Start sending a frame every ``period`` s (canopen's SYNC producer and heartbeats use
        this): a timing process where the bus has one, the bus' own timer where it has one, else
        a :class:`GridPeriodicTask`."""
        periodic = getattr(self.bus, "periodic", None)
        if periodic is not None and not remote:
            return periodic(can_id, data, period)
        if self.timer_periodic:
            return super().send_periodic(can_id, data, period, remote)
        return GridPeriodicTask(self, can_id, data, period, remote)


class GridPeriodicTask:
    """A frame sent from a thread on the time grid ``start + k * period``.

    python-can's thread-based periodic send catches up after the thread was held up (a host
    hiccup, a garbage collection): it sends the missed frames back to back. For SYNC that burst
    gives the drives several cycles in a row before the master could answer the first with its
    set-points. Here a slot the thread wakes up too late for is skipped instead (counted in
    ``skipped``), and two frames are never closer than half a period, as with a hardware
    timer that cannot queue. The task ends by :meth:`stop`, or by itself once the network is
    disconnected.

    Args:
        network: the network whose bus sends (``network.send_message``, under its lock).
        can_id, data, remote: the frame.
        period: s between frames.
    """

    def __init__(self, network: canopen.Network, can_id: int, data: bytes, period: float,
                 remote: bool = False):
        if not period > 0:
            raise ValueError(f"period must be positive, got {period!r}")
        self.period = period
        self.msg = can.Message(arbitration_id=can_id, data=bytes(data), is_remote_frame=remote,
                               is_extended_id=can_id > 0x7FF)
        self.sent = 0       # frames sent
        self.skipped = 0    # grid slots left out because the thread woke up too late
        self.failed = 0     # slots whose frame the bus refused
        self._network = network
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"periodic-0x{can_id:03X}", daemon=True)
        self._thread.start()

    def update(self, data: bytes) -> None:
        """Send ``data`` from the next slot on."""
        self.msg = can.Message(arbitration_id=self.msg.arbitration_id, data=bytes(data),
                               is_remote_frame=self.msg.is_remote_frame,
                               is_extended_id=self.msg.is_extended_id)

    def stop(self) -> None:
        """Stop sending (returns once the thread has ended)."""
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join()

    def _run(self) -> None:
        period = self.period
        due = time.perf_counter()
        while not self._stop.is_set():
            bus = self._network.bus
            if bus is None or getattr(bus, "_is_shutdown", False):
                break                          # the network was disconnected under the task: it ends
            try:
                with self._network.send_lock:
                    bus.send(self.msg)
                self.sent += 1
            except can.CanError as exc:       # e.g. a full transmit queue: the slot is lost
                self.failed += 1
                if self.failed == 1:
                    logger.warning("periodic frame 0x%03X not sent: %s", self.msg.arbitration_id, exc)
            due += period
            earliest = time.perf_counter() + 0.5 * period
            if due < earliest:
                missed = math.ceil((earliest - due) / period)
                self.skipped += missed
                due += missed * period
            self._stop.wait(due - time.perf_counter())


def open_network(config: BusConfig, timing=None) -> BusNetwork:
    """Open the bus and connect a :class:`BusNetwork` (with its notifier thread) to it; with
    ``timing`` (:class:`drivers.timing.TimingConfig`) as it says: through a timing process where
    it asks for one (:class:`drivers.timing.TimedBus`)."""
    bus = open_bus(config) if timing is None else timing.open(config)
    network = BusNetwork(bus, config)
    network.connect()
    return network


def notifier_of(network: canopen.Network) -> can.Notifier:
    """The notifier thread of a connected ``network`` (canopen's ``Network.notifier``), which
    listeners are added to and removed from.

    Raises:
        ~drivers.errors.ConfigError: the network is not connected (:func:`open_network` connects it).
    """
    if network.notifier is None:
        raise ConfigError("the CANopen network is not connected (no notifier): open it with drivers.bus.open_network")
    return network.notifier


def frame_bits(n_bytes: int) -> int:
    """Worst-case length in bits of a classic CAN frame with an 11-bit identifier.

    47 bits of frame overhead (incl. 3 bits interframe space) plus the data, plus one stuff bit
    per 4 bits of the 34 + 8n stuffable bits: 135 bits for 8 data bytes, 55 for a SYNC.
    """
    if not 0 <= n_bytes <= 8:
        raise ValueError(f"a classic CAN frame holds 0..8 data bytes, got {n_bytes}")
    stuffable = 34 + 8 * n_bytes
    return 47 + 8 * n_bytes + (stuffable - 1) // 4


def cycle_bits(frame_sizes: Iterable[int]) -> int:
    """Worst-case bits on the bus for the frames of one SYNC cycle (sizes in bytes)."""
    return sum(frame_bits(n) for n in frame_sizes)


def check_bus_load(cycle_frame_sizes: Iterable[int], period: float, bitrate: int | None,
                   background_bits_per_s: float = 0.0, max_load: float = 1.0) -> float:
    """Refuse a run whose worst-case traffic does not fit the bitrate.

    Args:
        cycle_frame_sizes: data length in bytes of every frame sent once per SYNC cycle
            (the SYNC itself included).
        period: SYNC period in s.
        bitrate: bus bitrate in bit/s; ``None`` skips the check (returns 0).
        background_bits_per_s: traffic that is not per cycle (heartbeats).
        max_load: accepted fraction of the bitrate.

    Returns:
        The worst-case bus load as a fraction of the bitrate.

    Raises:
        BusLoadError: the load exceeds ``max_load``; the message gives the numbers.
    """
    sizes = list(cycle_frame_sizes)
    if period <= 0:
        raise ConfigError(f"SYNC period must be positive, got {period!r} s")
    if bitrate is None:
        return 0.0
    bits = cycle_bits(sizes)
    load = (bits / period + background_bits_per_s) / bitrate
    if load > max_load:
        ceiling = max_sync_rate(sizes, bitrate, background_bits_per_s, max_load)
        raise BusLoadError(
            f"bus load {load:.0%} of {bitrate} bit/s: {len(sizes)} frames = {bits} bits per SYNC "
            f"cycle (worst-case stuffing) every {period * 1e3:g} ms; the shortest SYNC period this "
            f"bus can carry is {1e3 / ceiling:.2f} ms ({ceiling:.0f} Hz)")
    return load


def max_sync_rate(cycle_frame_sizes: Iterable[int], bitrate: int,
                  background_bits_per_s: float = 0.0, max_load: float = 1.0) -> float:
    """Highest SYNC rate in Hz whose worst-case traffic fits ``max_load`` of ``bitrate``
    (arguments as for :func:`check_bus_load`); 0 when the background alone does not fit."""
    spare = max_load * bitrate - background_bits_per_s
    return max(spare, 0.0) / cycle_bits(cycle_frame_sizes)
