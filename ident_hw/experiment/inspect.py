"""Read-only looks at the bus: which nodes answer (``ident-hw scan``) and what every configured
drive is doing (``ident-hw monitor``). Nothing here writes to a drive."""

from __future__ import annotations

import struct
import time
from dataclasses import dataclass

import canopen
from canopen.profiles.p402 import State402
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from drivers.epos import DriveGroup
from drivers.errors import NodeError
from drivers.profiles import VENDOR_ID_MAXON
from ident_hw.config import Config


def cia402_state(statusword: int) -> str:
    """CiA 402 state name of a statusword (canopen's masks)."""
    return next((name for name, (mask, value) in State402.SW_MASK.items() if statusword & mask == value),
                "UNKNOWN")


@dataclass
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


def read_node(network: canopen.Network, node_id: int, heartbeat_wait: float = 1.0,
              sdo_timeout: float = 0.5) -> NodeInfo:
    """Identity, device name, firmware (0x100A), NMT state (heartbeat) and CiA 402 state of a node."""
    node = network.nodes.get(node_id)
    if node is None:
        node = canopen.RemoteNode(node_id, canopen.ObjectDictionary())
        network.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = sdo_timeout
    try:
        nmt = node.nmt.wait_for_heartbeat(heartbeat_wait)
    except canopen.nmt.NmtError:
        nmt = "unknown (no heartbeat)"
    status = _upload(node, 0x6041)
    return NodeInfo(node_id=node_id, device_name=_text(_upload(node, 0x1008)), firmware=_text(_upload(node, 0x100A)),
                    vendor_id=_u32(_upload(node, 0x1018, 1)), product_code=_u32(_upload(node, 0x1018, 2)),
                    revision=_u32(_upload(node, 0x1018, 3)), nmt_state=nmt,
                    cia402_state=cia402_state(struct.unpack_from("<H", status)[0]) if status else None)


def scan(network: canopen.Network, wait: float = 1.0) -> list[int]:
    """Node-IDs that answer an SDO request (canopen's scanner over 1..127), sorted."""
    network.scanner.reset()
    network.scanner.search()
    time.sleep(wait)
    return sorted(set(network.scanner.nodes))


def compare(config: Config, found: dict[int, NodeInfo]) -> list[str]:
    """Differences between the config's actuators and the nodes found; empty when they match."""
    problems = []
    for act in config.robot.actuators:
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


def snapshot(group: DriveGroup) -> list[dict]:
    """One row per drive: NMT and CiA 402 state, position, velocity, current (SI), error (SDO reads)."""
    rows = []
    for drive in group.drives:
        s, p = drive.axis.scaling, drive.profile
        nmt = drive.node.nmt
        row = {"drive": drive.label, "nmt": nmt.state if nmt.timestamp is not None else "no heartbeat"}
        try:
            row["state"] = drive.state
            row["position"] = drive.position()
            row["velocity"] = drive.read(p.velocity_actual) / s.rpm_per_unit_velocity
            row["current"] = drive.read(p.current_actual) * 1e-3
            row["error"] = drive.error_text()
        except NodeError as exc:
            row["state"] = f"no answer ({exc})"
        rows.append(row)
    return rows


def format_snapshot(rows: list[dict]) -> str:
    """The monitor's table (units: rad or m, rad/s or m/s, A)."""
    lines = [f"{'drive':<18} {'NMT':<16} {'CiA 402':<24} {'position':>11} {'velocity':>10} {'current':>8}  error"]
    for r in rows:
        if "position" not in r:
            lines.append(f"{r['drive']:<18} {r['nmt']:<16} {r['state']}")
            continue
        lines.append(f"{r['drive']:<18} {r['nmt']:<16} {r['state']:<24} {r['position']:>11.6f} "
                     f"{r['velocity']:>10.5f} {r['current']:>8.3f}  {r['error']}")
    return "\n".join(lines)
