"""What a run asks of a drive's firmware: the objects the master reads or writes for each use, and
the drive (or a dictionary file standing for it) checked against them before anything moves.

A drive generation's firmware versions differ in their objects: maxon's EDS of the EPOS4 for
firmware 0x0110 has no ``0x60C2``, the interpolation period every cyclic stream writes (CSP),
which its DCF of firmware 0x0170 has (:attr:`drivers.profiles.DriveProfile.firmware_gaps`). Such
a drive would fail only after homing and the move to the start. So at bring-up the master asks
the drive itself for every object the run will use (an SDO upload each; "no such object" or "no
such sub-index" is an absence, :func:`absent`) and refuses it, naming the node, its firmware
(``0x1018:03``, the version in its upper 16 bits) and the objects, with what maxon's files say
(:func:`refusal`). A dictionary file (``object_dictionary:`` of an actuator) is held to the same
list (:func:`load_object_dictionary`): maxon's older EDS is accepted where the run needs nothing
it lacks (``ident-hw home`` on it, not ``run``).

The uses (:data:`USES`): ``bring_up`` (identity, the CiA 402 state machine, limits, PDO mapping,
heartbeats, naming a fault, the positions), ``home`` (CiA 402 homing), ``move`` (profile position
to a trajectory's start), ``stream`` (the cyclic mode and the objects of its PDOs).
"""

from __future__ import annotations

import os
from typing import Iterable, Mapping

import canopen
from canopen.objectdictionary import ObjectDictionary

from drivers.profiles import INSTANTANEOUS, DriveProfile, ObjectRef, find_variable, get_profile

#: what a run may ask of a drive (see the module docstring)
USES = ("bring_up", "home", "move", "stream")

#: the CiA 301 abort codes of an object the drive does not have: no such object, no such sub-index
ABSENT_CODES = (0x06020000, 0x06090011)

#: the drive's revision number (``0x1018:03``): its firmware version in the upper 16 bits on maxon's drives
REVISION = (0x1018, 3)


def objects_used(profile: DriveProfile | str, current: str = INSTANTANEOUS,
                 uses: Iterable[str] = USES) -> dict[tuple[int, int], str]:
    """``(index, sub-index)`` of every object the master reads or writes on a drive of ``profile``
    for ``uses`` (each of :data:`USES`), streaming the ``current`` (instantaneous or averaged),
    with what it is for (for messages); in index order."""
    p = get_profile(profile)
    uses = set(uses)
    unknown = uses - set(USES)
    if unknown:
        raise ValueError(f"unknown uses {sorted(unknown)}; known: {USES}")
    used: dict[tuple[int, int], str] = {}

    def add(ref: ObjectRef | tuple[int, int] | None, what: str) -> None:
        if ref is not None:
            key = (ref.index, ref.subindex) if isinstance(ref, ObjectRef) else ref
            used.setdefault(key, what)

    if "bring_up" in uses:
        add((0x1001, 0), "error register (naming a fault)")
        add((0x1008, 0), "device name (identity)")
        add((0x1016, 1), "consumer heartbeat time (the drive's watch of the master)")
        add((0x1017, 0), "producer heartbeat time")
        add((0x1018, 1), "vendor-ID (identity)")
        add((0x1018, 2), "product code (identity)")
        add(REVISION, "revision number (the firmware)")
        for n in range(p.tpdo_count):
            add((0x1800 + n, 1), f"TPDO{n + 1} COB-ID")
            add((0x1800 + n, 2), f"TPDO{n + 1} transmission type")
            add((0x1A00 + n, 0), f"TPDO{n + 1} mapping")
        for n in range(p.rpdo_count):
            add((0x1400 + n, 1), f"RPDO{n + 1} COB-ID")
            add((0x1400 + n, 2), f"RPDO{n + 1} transmission type")
            add((0x1600 + n, 0), f"RPDO{n + 1} mapping")
        add(p.statusword, "statusword")
        add(p.controlword, "controlword")
        add(p.modes_of_operation, "modes of operation")
        add(p.modes_display, "modes of operation display")
        add(p.error_code, "error code (naming a fault)")
        add(p.position_actual, "position actual value")
        add(p.current_limit, "current limit (bring-up)")
        add(p.max_profile_velocity, "max profile velocity (bring-up)")
        for ref in p.software_position_limit:
            add(ref, "software position limit (bring-up)")
        add(p.following_error_window, "following error window (bring-up)")
    if "home" in uses:
        add(p.homing_method, "homing method (homing)")
        add(p.home_position, "home position (homing)")
        for ref in p.homing_speeds:
            add(ref, "homing speed (homing)")
        add(p.homing_acceleration, "homing acceleration (homing)")
    if "move" in uses or "stream" in uses:      # a stream ends holding its last set-point in profile position
        add(p.target_position, "target position (profile moves)")
    if "move" in uses:
        add(p.profile_velocity, "profile velocity (profile moves)")
        add(p.profile_acceleration, "profile acceleration (profile moves)")
        add(p.profile_deceleration, "profile deceleration (profile moves)")
    if "stream" in uses:
        add(p.cyclic_target, "the cyclic set-point (the stream's RPDO)")
        if p.interpolation_period is not None:
            ip = p.interpolation_period
            add(ip, "interpolation time period (the cyclic stream writes it: CSP)")
            add((ip.index, ip.subindex + 1), "interpolation time index (the cyclic stream writes it: CSP)")
        add(p.velocity_actual, "velocity actual value (the stream's TPDO)")
        add(p.streamed_current(current), f"the {current} current (the stream's TPDO)")
    return dict(sorted(used.items()))


def firmware_of(revision: int | None) -> int | None:
    """The firmware version in a maxon drive's revision number ``0x1018:03`` (its upper 16 bits)."""
    return None if revision is None else (revision >> 16) & 0xFFFF


def absent(sdo, keys: Iterable[tuple[int, int]]) -> list[tuple[int, int]]:
    """The objects of ``keys`` the drive behind ``sdo`` (a :class:`canopen.sdo.SdoClient`) does not
    have: its SDO server aborts their upload with "no such object" or "no such sub-index"
    (:data:`ABSENT_CODES`). Another abort (a write-only object) is an object it has. A timeout
    raises :class:`canopen.sdo.SdoCommunicationError`."""
    missing = []
    for index, subindex in keys:
        try:
            sdo.upload(index, subindex)
        except canopen.sdo.SdoAbortedError as exc:
            if exc.code in ABSENT_CODES:
                missing.append((index, subindex))
    return missing


def refusal(profile: DriveProfile, firmware: int | None, missing: Iterable[tuple[int, int]],
            used: Mapping[tuple[int, int], str], where: str = "") -> str:
    """Why a drive (``where``: or a dictionary file) cannot run: its firmware, each missing object
    with what the run uses it for, and what maxon's files say of them."""
    missing = list(missing)
    version = "unknown firmware" if firmware is None else f"firmware 0x{firmware:04X}"
    objects = "; ".join(f"0x{i:04X}:{s:02X} ({used.get((i, s), 'used by the master')})" for i, s in missing)
    notes = [note for gap in profile.firmware_gaps if set(gap.lacks) & set(missing)
             for note in [gap.says(firmware)] if note]
    return f"{profile.name} {version}{where} lacks {objects}" + (f" ({'; '.join(notes)})" if notes else "")


def load_object_dictionary(path: str | os.PathLike, profile_name: str | DriveProfile, node_id: int,
                           current: str = INSTANTANEOUS, uses: Iterable[str] = USES) -> ObjectDictionary:
    """A drive's own object dictionary from an EDS or DCF file (maxon's, or one saved from the
    drive), for the master to use instead of the built-in one, checked against the objects the
    run uses (:func:`objects_used`).

    Raises:
        ValueError: the file cannot be read, or lacks objects the run uses (all of them listed,
            with the file's firmware and what maxon's files say), so that nothing moves on a
            dictionary that does not fit.
    """
    prof = get_profile(profile_name)
    if not os.path.isfile(path):
        raise ValueError(f"object dictionary {path}: no such file")
    try:
        od = canopen.import_od(os.fspath(path), node_id)
    except Exception as exc:   # canopen raises what its parsers raise
        raise ValueError(f"object dictionary {path}: not a readable EDS/DCF ({exc})") from exc
    used = objects_used(prof, current, uses)
    missing = [key for key in used if find_variable(od, *key) is None]
    if missing:
        revision = find_variable(od, *REVISION)
        firmware = firmware_of(revision.default if revision is not None and isinstance(revision.default, int) else None)
        raise ValueError(f"object dictionary {path}: {refusal(prof, firmware, missing, used, where=' (the file)')}, "
                         f"which the master uses for this command")
    return od
