"""Read-only looks at the bus: which nodes answer (``ident-hw scan``) and what every configured
drive is doing (``ident-hw monitor``). Nothing here writes to a drive."""

from __future__ import annotations

import struct
import time
from collections.abc import Sequence
from dataclasses import dataclass

import can
import canopen
from canopen.nmt import NMT_STATES
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from drivers.bus import notifier_of
from drivers.cia import state_of
from drivers.epos import DriveGroup
from drivers.errors import NodeError
from drivers.profiles import VENDOR_ID_MAXON
from ident_hw.config import Config


@dataclass(frozen=True)
class NodeInfo:
    """What a node tells about itself over SDO (``None`` where it did not answer)."""

    node_id: int
    device_name: str | None
    firmware: str | None
    vendor_id: int | None
    product_code: int | None
    revision: int | None
    nmt_state: str
    cia402_state: str | None

    def describe(self) -> str:
        ident = (f"vendor 0x{self.vendor_id:08X}, product 0x{self.product_code:08X}, revision 0x{self.revision:08X}"
                 if None not in (self.vendor_id, self.product_code, self.revision) else "identity unreadable")
        return (f"node {self.node_id:3d}: {self.device_name or '?'} (firmware {self.firmware or '?'}), {ident}, "
                f"NMT {self.nmt_state}, CiA 402 {self.cia402_state or '-'}")


def _upload(node: canopen.RemoteNode, index: int, subindex: int = 0) -> bytes | None:
    try:
        return node.sdo.upload(index, subindex)
    except (SdoAbortedError, SdoCommunicationError):
        return None


def _u32(data: bytes | None) -> int | None:
    return struct.unpack_from("<I", data.ljust(4, b"\0"))[0] if data else None


def _text(data: bytes | None) -> str | None:
    return data.rstrip(b"\0").decode("latin-1") if data is not None else None


def nmt_state(heard: int | None, answers_sdo: bool, heartbeat_ms: int | None) -> str:
    """The NMT state of a node from what the bus showed, without node guarding.

    ``heard``: the state byte of its last heartbeat or boot-up message (None: none seen);
    ``answers_sdo``: it answered an SDO request; ``heartbeat_ms``: its producer heartbeat time
    (0x1017) if read. A boot-up message means PRE-OPERATIONAL (the node enters it by itself);
    a node that answers SDO without sending heartbeats (0x1017 = 0, as after power-up) is
    PRE-OPERATIONAL or OPERATIONAL: a STOPPED node does not answer SDO (CiA 301).
    """
    if heard is not None:
        state = NMT_STATES.get(heard & 0x7F, f"0x{heard:02X}")
        return "PRE-OPERATIONAL (boot-up seen)" if heard == 0 else state
    if answers_sdo:
        why = "heartbeat off: 0x1017 = 0" if heartbeat_ms == 0 else "no heartbeat seen"
        return f"PRE-OPERATIONAL or OPERATIONAL (answers SDO; {why})"
    return "unknown (no heartbeat, no SDO answer)"


class NmtListener(can.Listener):
    """The last heartbeat / boot-up state byte of every node (COB-ID 0x701..0x77F) seen on the bus."""

    def __init__(self) -> None:
        self.states: dict[int, int] = {}

    def on_message_received(self, msg: can.Message) -> None:
        if (0x701 <= msg.arbitration_id <= 0x77F and not msg.is_extended_id and not msg.is_remote_frame
                and len(msg.data) == 1):
            self.states[msg.arbitration_id - 0x700] = msg.data[0]


def read_node(network: canopen.Network, node_id: int, heard: int | None = None,
              sdo_timeout: float = 0.5) -> NodeInfo:
    """Identity, device name, firmware, NMT state (:func:`nmt_state`; ``heard`` = the state byte
    of a heartbeat or boot-up seen from it) and CiA 402 state of a node. A maxon drive's firmware
    is the high word of its revision number ``0x1018:03`` (``0x2126`` in ``0x21260000``; neither
    EPOS has ``0x100A``), another node's the software version ``0x100A``.

    Raises:
        NodeError: ``node_id`` is a local node of ``network`` (served by this process, not read).
    """
    known = network.nodes.get(node_id)
    if isinstance(known, canopen.LocalNode):
        raise NodeError(f"node {node_id}", "a local node of this network (served by this process), not a node to read")
    node = known if known is not None else canopen.RemoteNode(node_id, canopen.ObjectDictionary())
    if known is None:
        network.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = sdo_timeout
    name = _upload(node, 0x1008)
    identity = [_u32(_upload(node, 0x1018, sub)) for sub in (1, 2, 3)]
    heartbeat = _upload(node, 0x1017)
    answers = name is not None or heartbeat is not None or identity[0] is not None
    status = _upload(node, 0x6041)
    firmware: str | None
    if identity[0] == VENDOR_ID_MAXON and identity[2] is not None:
        firmware = f"0x{identity[2] >> 16:04X}"
    else:
        firmware = _text(_upload(node, 0x100A))
    return NodeInfo(node_id=node_id, device_name=_text(name), firmware=firmware,
                    vendor_id=identity[0], product_code=identity[1], revision=identity[2],
                    nmt_state=nmt_state(heard, answers, struct.unpack_from("<H", heartbeat)[0] if heartbeat else None),
                    cia402_state=state_of(struct.unpack_from("<H", status)[0]) if status else None)


def scan(network: canopen.Network, wait: float = 1.0) -> dict[int, int | None]:
    """Nodes on the bus: those that answer an SDO request (canopen's scanner over 1..127) or send
    a heartbeat within ``wait`` s, each with the state byte of its last heartbeat (None: none)."""
    listener = NmtListener()
    notifier = notifier_of(network)
    notifier.add_listener(listener)
    try:
        network.scanner.reset()
        network.scanner.search()
        time.sleep(wait)
    finally:
        notifier.remove_listener(listener)
    found = set(network.scanner.nodes) | set(listener.states)
    return {i: listener.states.get(i) for i in sorted(found)}


def compare(config: Config, found: dict[int, NodeInfo]) -> list[str]:
    """Differences between the config's actuators and the nodes found; empty when they match."""
    problems = []
    for act in config.robot.actuators:
        if act.node_id is None or act.profile is None:
            problems.append(f"{act.name}: no node_id and profile in the config, no drive to look for")
            continue
        info = found.get(act.node_id)
        where = f"{act.name} (node {act.node_id})"
        if info is None:
            problems.append(f"{where}: configured, but no node {act.node_id} answers")
            continue
        expected = act.profile.upper()
        if not (info.device_name or "").upper().startswith(expected):
            problems.append(f"{where}: device name {info.device_name!r}, configured profile {act.profile!r}")
        if info.vendor_id is not None and info.vendor_id != VENDOR_ID_MAXON:
            problems.append(f"{where}: vendor-ID 0x{info.vendor_id:08X} is not maxon")
        if act.product_code is not None and info.product_code != act.product_code:
            problems.append(f"{where}: product code {info.product_code}, configured {act.product_code}")
    configured = {a.node_id for a in config.robot.actuators}
    for node_id in sorted(set(found) - configured):
        problems.append(f"node {node_id}: on the bus, not in the config")
    return problems


@dataclass(frozen=True)
class DriveSnapshot:
    """One drive as the monitor shows it (:func:`snapshot`): its label, NMT state (heard, or
    guessed from whether it answered), CiA 402 state (or why it gave no answer) and, where it
    answered, its position (rad or m), velocity (rad/s or m/s), current (A) and error text."""

    drive: str
    nmt: str
    state: str
    position: float | None = None
    velocity: float | None = None
    current: float | None = None
    error: str = ""


def snapshot(group: DriveGroup) -> list[DriveSnapshot]:
    """One row per drive: NMT and CiA 402 state, position, velocity, current (SI), error (SDO reads)."""
    rows = []
    for drive in group.drives:
        s, p = drive.axis.scaling, drive.profile
        nmt = drive.node.nmt
        position = velocity = current = None
        try:
            state = drive.state
            position = drive.position()
            velocity = s.velocity_from_rpm(drive.read(p.velocity_actual))
            current = s.current_from_ma(drive.read(p.current_actual))
            error = drive.error_text()
        except NodeError as exc:
            state, error = f"no answer ({exc})", ""
        heard = nmt.state if nmt.timestamp is not None else None
        guessed = nmt_state(None, position is not None, None).split(" (")[0]
        rows.append(DriveSnapshot(drive.label, heard or guessed, state, position, velocity, current, error))
    return rows


def format_snapshot(rows: Sequence[DriveSnapshot]) -> str:
    """The monitor's table (units: rad or m, rad/s or m/s, A)."""
    lines = [f"{'drive':<18} {'NMT':<30} {'CiA 402':<24} {'position':>11} {'velocity':>10} {'current':>8}  error"]
    for r in rows:
        if r.position is None or r.velocity is None or r.current is None:
            lines.append(f"{r.drive:<18} {r.nmt:<30} {r.state}")
            continue
        lines.append(f"{r.drive:<18} {r.nmt:<30} {r.state:<24} {r.position:>11.6f} "
                     f"{r.velocity:>10.5f} {r.current:>8.3f}  {r.error}")
    return "\n".join(lines)
