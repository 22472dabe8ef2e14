"""Maxon EPOS2 / EPOS4 drive profiles as data, and their CANopen object dictionaries.

Both sides use this module: the master (``canopen.RemoteNode``) and the emulated drives of
:mod:`drivers.sim` (``canopen.LocalNode``) build the same object dictionary with
:func:`make_object_dictionary`, so an index, a data type or an access right can only be wrong
in one place. A :class:`DriveProfile` names the objects the driver reads and writes: where each
fact lives on that generation (the master asks the profile, never which generation it talks
to); the object dictionary holds them with their data types, access rights, defaults and
PDO-mappable flags, plus the CiA 301 communication objects (PDO parameters, heartbeat, EMCY,
identity).

Both dictionaries agree with maxon's own files for every object defined here
(``tests/test_real_od.py`` and ``tests/test_real_od_epos2.py``, given the files; the facts the
master depends on are written out there too): the EPOS4's with maxon's EDS (firmware 0x0110)
and a DCF (firmware 0x0170), the EPOS2's with maxon's EDS of the EPOS2 70/10 (firmware 0x2126)
and a DCF read from such a drive, in existence, data type, access and PDO mapping, and in the
defaults the project relies on. Neither generation has a PDO event timer (no sub-index 5 in
the PDO parameter records: no TPDO event timer, no RPDO deadline), ``0x1006``, ``0x1009`` or
``0x100A``; the master's PDO layout therefore uses no event timer
(:func:`drivers.acquisition.pdo_layout`). Both keep five entries of error history ``0x1003``
and watch up to two heartbeat producers (``0x1016:01..02``).

What the EPOS2 lacks, and what the profile names instead:

* no ``0x603F`` (error code): the code of the present error is the newest entry of the
  pre-defined error field, ``0x1003:01`` (bits 0-15; it stays after a fault reset, so it names
  a present error only while the error register ``0x1001`` shows one);
* no ``0x60F4``: the following error actual value is ``0x20F4`` (INTEGER16);
* no ``0x605A`` (quick stop option code): its quick stop is fixed;
* its averaged current is ``0x2027`` (INTEGER16, mA), the EPOS4's ``0x30D1:01`` (INTEGER32).

Both averaged currents are a running first-order low-pass of the current with a 50 Hz cut-off
(maxon's firmware specifications), run at the rate of the current loop: 25 kHz on the EPOS4,
10 kHz on the EPOS2 (their hardware references' sampling rate of the PI current controller);
:class:`AveragingFilter`, ``DriveProfile.current_averaging``.

Other differences kept as on the real devices: the EPOS2 reports its current in ``0x6078``
(I16, mA) and has no ``0x30D1`` or torque-constant object; the EPOS4 reports it in ``0x30D1:02``
(I32, mA) and has no ``0x6078``. The EPOS2 streams positions through its maxon "position mode"
(mode -1, set-point ``0x2062``), the EPOS4 through CSP (mode 8, ``0x607A``, its interpolation
period ``0x60C2``). The EPOS2 has no CSP: its interpolated position mode (IPM, mode 7:
``0x60C0``, ``0x60C2``, ``0x20C1``, a buffer of PVT points) is not used, and those objects are
not defined here. ``0x1005`` (SYNC COB-ID) and ``0x1014`` (EMCY COB-ID) are writable on the EPOS2, not
on the EPOS4. Further EPOS2 facts, from public EPOS drivers that reproduce maxon's firmware
specification (re-check against the "EPOS2 Firmware Specification" when it is in reach):

* Homing: the EPOS2 has the CiA 402 "home offset" ``0x607C`` and the maxon "home position"
  ``0x2081``; the EPOS4 has no ``0x607C`` but "home position" ``0x30B0`` and "home offset move
  distance" ``0x30B1`` (INTEGER32, qc; EPOS4 firmware specification section 6.2.67 as cited by
  those drivers). Both generations assign the home position when homing completes.
* Software position limits ``0x607D``: a position outside them faults the drive with
  "software position limit error", ``0xFF09`` on the EPOS2 and ``0x8A82`` on the EPOS4 (their
  EMCY tables; ``0x8611`` is the following error on both). Targets are limited to the range
  (CiA 402).
* EMCY COB-ID ``0x1014`` of the EPOS2: read-write with CiA 301 semantics (bit 31 = no EMCY; the CAN-ID may
  only change while invalid).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from types import MappingProxyType
from typing import Any, Mapping, Optional

from canopen.objectdictionary import (
    ObjectDictionary,
    ODArray,
    ODRecord,
    ODVariable,
    datatypes,
)

from drivers.cia import EMCY_COB_BASE, MODE_PPM, SYNC_COB_ID, is_node_id, pdo_cob_id

VENDOR_ID_MAXON = 0x000000FB


@dataclass(frozen=True)
class ObjectRef:
    """One object of a drive's object dictionary.

    Args:
        index: 16-bit object index.
        subindex: sub-index (0 for a plain variable).
        data_type: CANopen data type name as in :mod:`canopen.objectdictionary.datatypes`,
            e.g. ``"INTEGER32"``.
        unit: drive unit of the raw value (``"qc"`` quadrature counts, ``"rpm"``, ``"mA"``, ...).
    """

    index: int
    subindex: int
    data_type: str
    unit: str = ""

    def __post_init__(self) -> None:
        if not isinstance(getattr(datatypes, self.data_type, None), int):
            raise ValueError(f"unknown CANopen data type {self.data_type!r} for 0x{self.index:04X}")

    @cached_property
    def type_code(self) -> int:
        """The CANopen data type code (``canopen.objectdictionary.datatypes``)."""
        return getattr(datatypes, self.data_type)

    @cached_property
    def bits(self) -> int:
        """Size in bits (the length used in a PDO mapping entry)."""
        return ODVariable.STRUCT_TYPES[self.type_code].size * 8

    @cached_property
    def key(self) -> tuple[int, int]:
        """``(index, subindex)``."""
        return self.index, self.subindex

    @cached_property
    def value_range(self) -> tuple[int, int]:
        """The smallest and largest value of the (integer) data type."""
        if self.type_code in datatypes.SIGNED_TYPES:
            return -(1 << (self.bits - 1)), (1 << (self.bits - 1)) - 1
        return 0, (1 << self.bits) - 1

    def __str__(self) -> str:
        return f"0x{self.index:04X}:{self.subindex:02X}"


#: Hz, cut-off of a drive's averaged current: maxon's firmware specifications of both
#: generations define it as the current actual value "filtered by 1st order digital low-pass
#: filter with a cut-off frequency of 50 Hz"
AVERAGING_CUTOFF = 50.0


@dataclass(frozen=True)
class AveragingStep:
    """One SYNC period of a running average, ``y1 = pole y0 + b0 x0 + b1 x1``
    (:meth:`AveragingFilter.over_period`): the weights (dimensionless, ``pole + b0 + b1 = 1``) of
    the output ``y0`` at the period's start and of the current at its start ``x0`` and end ``x1``.

    Attributes:
        pole: the weight of the previous output, ``a ** N`` (``a`` the loop-rate pole).
        b0: the weight of the current at the period's start.
        b1: the weight of the current at the period's end.
    """

    pole: float
    b0: float
    b1: float


@dataclass(frozen=True)
class AveragingFilter:
    """The running average behind a drive's averaged current (``current_averaged``): a
    first-order digital low-pass of cut-off ``cutoff`` (Hz) run at the current loop's sample
    rate ``rate`` (Hz) on the current it measures,

        ``y[n] = a y[n-1] + (1 - a) x[n]``,  ``a = exp(-2 pi cutoff / rate)``

    (the analogue filter's pole mapped to the loop rate; maxon does not publish the
    discretisation, and at the loop rate the usual ones differ by less than one loop sample of
    delay). Its time constant is ``1 / (2 pi cutoff)``, 3.2 ms at 50 Hz.

    :meth:`over_period` is the same filter seen at the SYNC rate: the exact result of the
    ``N = period * rate`` loop samples of a SYNC period over which the current runs linearly
    between its samples at the period's two ends. The emulated drives run it; the
    identification filters the regressor by it (:func:`ident_hw.filtering.running_average`).
    """

    cutoff: float
    rate: float

    def __post_init__(self) -> None:
        if not 0 < self.cutoff < 0.5 * self.rate:
            raise ValueError(f"averaging filter: need 0 < cutoff < rate / 2, got {self.cutoff} Hz at {self.rate} Hz")

    def over_period(self, period: float) -> AveragingStep:
        """``A, B0, B1`` (:class:`AveragingStep`) with ``y1 = A y0 + B0 x0 + B1 x1``: the filter's output ``y1`` at the
        end of a ``period`` (s) from its output ``y0`` at the start, for a current running
        linearly from ``x0`` (the start) to ``x1`` (the end), sampled at the loop rate at
        ``n / rate``, ``n = 1 .. N``. ``A + B0 + B1 = 1`` (unit gain at rest); ``N`` need not be
        a whole number (the closed form is continuous in it); a period of 0 leaves ``y``."""
        n = period * self.rate
        if not n > 0:
            return AveragingStep(1.0, 0.0, 0.0)
        a = math.exp(-2.0 * math.pi * self.cutoff / self.rate)
        a_n = a ** n
        # x0's weight: (1 - a) times the sum over the samples k = 1..N of a^(N-k) (1 - k / N)
        b0 = (a - n * a_n + (n - 1.0) * a_n * a) / ((1.0 - a) * n)
        return AveragingStep(a_n, b0, 1.0 - a_n - b0)


@dataclass(frozen=True)
class FirmwareGap:
    """Objects a generation's older firmware lacks, as maxon's own files show them.

    Args:
        lacks: ``(index, sub-index)`` of the objects missing.
        known_without: the firmware version (``0x1018:03 >> 16``) of a maxon file without them.
        known_with: the firmware version of a maxon file with them (they came in between).
        source: the files, in words.
    """

    lacks: tuple[tuple[int, int], ...]
    known_without: int
    known_with: int
    source: str

    def says(self, firmware: int | None) -> str | None:
        """What the files say of these objects on ``firmware`` (None: nothing, it is as new as
        the file that has them)."""
        if firmware is not None and firmware >= self.known_with:
            return None
        return f"{self.source}: update the drive's firmware"


#: which motor current an axis streams: the drive's instantaneous sample (its "current actual
#: value") or its running average (its "current actual value averaged", a 50 Hz first-order
#: low-pass: :class:`AveragingFilter`)
INSTANTANEOUS, AVERAGED = "instantaneous", "averaged"
#: the currents a drive can stream: ``"instantaneous"``, ``"averaged"``
CURRENTS = (INSTANTANEOUS, AVERAGED)


@dataclass(frozen=True)
class DriveProfile:
    """Which objects a drive generation uses for what (indices, types and units as data).

    A field that is ``None`` names an object the generation does not have. ``error_code`` is
    where the code of the drive's present error is read: the CiA 402 error code ``0x603F``, or
    (a drive without it) the newest entry of the pre-defined error field ``0x1003:01``, whose
    bits 0-15 are the code; either counts only while the error register ``0x1001`` is not 0.
    ``current_actual`` is the drive's instantaneous current, ``current_averaged`` its running
    average; :meth:`streamed_current` is the one an axis streams (TPDO1,
    :func:`drivers.acquisition.pdo_layout`).
    """

    name: str
    device_name: str
    product_code: int
    revision_number: int
    position_actual: ObjectRef
    velocity_actual: ObjectRef
    current_actual: ObjectRef
    current_averaged: ObjectRef
    statusword: ObjectRef
    controlword: ObjectRef
    modes_of_operation: ObjectRef
    modes_display: ObjectRef
    cyclic_mode: int
    cyclic_target: ObjectRef
    interpolation_period: Optional[ObjectRef]
    torque_constant: Optional[ObjectRef]
    supported_modes: Mapping[int, str]
    current_limit: ObjectRef
    max_profile_velocity: ObjectRef
    software_position_limit: tuple[ObjectRef, ObjectRef]  # (min, max)
    following_error_window: ObjectRef
    following_error_actual: ObjectRef
    position_demand: ObjectRef
    home_offset: ObjectRef
    home_position: ObjectRef
    homing_method: ObjectRef
    homing_speeds: tuple[ObjectRef, ObjectRef]  # (switch search, zero search)
    homing_acceleration: ObjectRef
    profile_velocity: ObjectRef
    profile_acceleration: ObjectRef
    profile_deceleration: ObjectRef
    quick_stop_deceleration: ObjectRef
    quick_stop_option_code: Optional[ObjectRef]
    target_position: ObjectRef
    error_code: ObjectRef
    software_limit_error: int
    #: access of the CiA 301 objects SYNC COB-ID 0x1005, device name 0x1008, EMCY COB-ID 0x1014
    communication_access: Mapping[int, str]
    #: the filter behind ``current_averaged``, at the sample rate of the generation's current loop
    current_averaging: AveragingFilter
    tpdo_count: int = 4
    rpdo_count: int = 4
    max_tpdo_bytes: int = 8
    #: the PDO parameter records have sub-index 5 (TPDO event timer, RPDO deadline): neither
    #: EPOS2 nor EPOS4 has it; a variant of a profile with it emulates a drive that has
    pdo_event_timer: bool = False
    #: entries of the error history 0x1003
    error_history: int = 5
    #: objects an older firmware of the generation lacks (maxon's files)
    firmware_gaps: tuple[FirmwareGap, ...] = ()

    def streamed_current(self, which: str) -> ObjectRef:
        """The current object an axis streams: :data:`INSTANTANEOUS` ``current_actual``, or
        :data:`AVERAGED` ``current_averaged`` (the same data type on either generation: the PDO
        layout keeps its size)."""
        if which not in CURRENTS:
            raise ValueError(f"current must be one of {CURRENTS}, got {which!r}")
        return self.current_averaged if which == AVERAGED else self.current_actual


def _r(index: int, subindex: int, data_type: str, unit: str = "") -> ObjectRef:
    return ObjectRef(index, subindex, data_type, unit)


_COMMON: dict[str, Any] = dict(
    position_actual=_r(0x6064, 0, "INTEGER32", "qc"),
    velocity_actual=_r(0x606C, 0, "INTEGER32", "rpm"),
    statusword=_r(0x6041, 0, "UNSIGNED16"),
    controlword=_r(0x6040, 0, "UNSIGNED16"),
    modes_of_operation=_r(0x6060, 0, "INTEGER8"),
    modes_display=_r(0x6061, 0, "INTEGER8"),
    max_profile_velocity=_r(0x607F, 0, "UNSIGNED32", "rpm"),
    software_position_limit=(_r(0x607D, 1, "INTEGER32", "qc"), _r(0x607D, 2, "INTEGER32", "qc")),
    following_error_window=_r(0x6065, 0, "UNSIGNED32", "qc"),
    position_demand=_r(0x6062, 0, "INTEGER32", "qc"),
    homing_method=_r(0x6098, 0, "INTEGER8"),
    homing_speeds=(_r(0x6099, 1, "UNSIGNED32", "rpm"), _r(0x6099, 2, "UNSIGNED32", "rpm")),
    homing_acceleration=_r(0x609A, 0, "UNSIGNED32", "rpm/s"),
    profile_velocity=_r(0x6081, 0, "UNSIGNED32", "rpm"),
    profile_acceleration=_r(0x6083, 0, "UNSIGNED32", "rpm/s"),
    profile_deceleration=_r(0x6084, 0, "UNSIGNED32", "rpm/s"),
    quick_stop_deceleration=_r(0x6085, 0, "UNSIGNED32", "rpm/s"),
    target_position=_r(0x607A, 0, "INTEGER32", "qc"),
)

#: the newest entry of the pre-defined error field (CiA 301): bits 0-15 the error code
NEWEST_ERROR = _r(0x1003, 1, "UNSIGNED32")

# maxon's EDS of the EPOS2 70/10 (firmware 0x2126) and a DCF read from such a drive
EPOS2 = DriveProfile(
    name="EPOS2",
    device_name="EPOS2 70/10",
    product_code=0x64200000,          # 0x1018:02 of the drive (the EDS's ProductNumber)
    revision_number=0x21260000,       # firmware 0x2126
    current_actual=_r(0x6078, 0, "INTEGER16", "mA"),
    current_averaged=_r(0x2027, 0, "INTEGER16", "mA"),
    following_error_actual=_r(0x20F4, 0, "INTEGER16", "qc"),   # no 0x60F4
    error_code=NEWEST_ERROR,                                    # no 0x603F
    quick_stop_option_code=None,                                # no 0x605A
    cyclic_mode=-1,
    cyclic_target=_r(0x2062, 0, "INTEGER32", "qc"),
    interpolation_period=None,
    torque_constant=None,
    supported_modes=MappingProxyType(
        {1: "PPM", 3: "PVM", 6: "HMM", 7: "IPM", -1: "position", -2: "velocity", -3: "current",
         -4: "diagnostic", -5: "master encoder", -6: "step/direction"}
    ),
    current_limit=_r(0x6410, 2, "UNSIGNED16", "mA"),
    home_offset=_r(0x607C, 0, "INTEGER32", "qc"),
    home_position=_r(0x2081, 0, "INTEGER32", "qc"),
    software_limit_error=0xFF09,
    communication_access=MappingProxyType({0x1005: "rw", 0x1008: "const", 0x1014: "rw"}),
    current_averaging=AveragingFilter(AVERAGING_CUTOFF, 10_000.0),   # PI current controller: 10 kHz
    **_COMMON,
)

EPOS4 = DriveProfile(
    name="EPOS4",
    device_name="EPOS4 50/5",
    product_code=0x65500000,
    revision_number=0x01700000,       # firmware 0x0170 (maxon's DCF of an EPOS4 50/15)
    current_actual=_r(0x30D1, 2, "INTEGER32", "mA"),
    current_averaged=_r(0x30D1, 1, "INTEGER32", "mA"),
    following_error_actual=_r(0x60F4, 0, "INTEGER32", "qc"),
    error_code=_r(0x603F, 0, "UNSIGNED16"),
    quick_stop_option_code=_r(0x605A, 0, "INTEGER16"),
    cyclic_mode=8,
    cyclic_target=_r(0x607A, 0, "INTEGER32", "qc"),
    interpolation_period=_r(0x60C2, 1, "UNSIGNED8", "ms"),
    torque_constant=_r(0x3001, 5, "UNSIGNED32", "uNm/A"),
    supported_modes=MappingProxyType(
        {1: "PPM", 3: "PVM", 6: "HMM", 8: "CSP", 9: "CSV", 10: "CST"}
    ),
    current_limit=_r(0x3001, 2, "UNSIGNED32", "mA"),
    home_offset=_r(0x30B1, 0, "INTEGER32", "qc"),   # "Home offset move distance"; no 0x607C
    home_position=_r(0x30B0, 0, "INTEGER32", "qc"),
    software_limit_error=0x8A82,
    # maxon's EPOS4 EDS (firmware 0x0110) and a DCF (firmware 0x0170): 0x1005 const, 0x1008 and
    # 0x1014 read-only
    communication_access=MappingProxyType({0x1005: "const", 0x1008: "ro", 0x1014: "ro"}),
    current_averaging=AveragingFilter(AVERAGING_CUTOFF, 25_000.0),   # PI current controller: 25 kHz
    # the CSP interpolation period, which every cyclic stream writes: absent from maxon's EDS of
    # firmware 0x0110 (the EPOS4 Module 50/8), present in its DCF of firmware 0x0170
    firmware_gaps=(FirmwareGap(((0x60C2, 1), (0x60C2, 2)), 0x0110, 0x0170,
                               "maxon's EDS of the EPOS4 for firmware 0x0110 has no 0x60C2 either, its DCF for "
                               "firmware 0x0170 has it"),),
    **_COMMON,
)

PROFILES: Mapping[str, DriveProfile] = MappingProxyType({"epos2": EPOS2, "epos4": EPOS4})

# CiA 402 0x6502 "supported drive modes" bit of each mode (maxon-specific modes in bits 16..21)
_MODE_BITS = {1: 0, 3: 2, 6: 5, 7: 6, 8: 7, 9: 8, 10: 9, -1: 16, -2: 17, -3: 18, -4: 19, -5: 20, -6: 21}


def get_profile(profile_name: str | DriveProfile) -> DriveProfile:
    """The profile called ``profile_name`` (``"epos2"`` or ``"epos4"``, case-insensitive); a
    :class:`DriveProfile` is its own profile (e.g. a variant made with ``dataclasses.replace``)."""
    if isinstance(profile_name, DriveProfile):
        return profile_name
    try:
        return PROFILES[profile_name.lower()]
    except (KeyError, AttributeError):
        raise ValueError(
            f"unknown drive profile {profile_name!r}; known: {', '.join(PROFILES)}"
        ) from None


# --- object dictionary construction ------------------------------------------------------


def _var(name, index, subindex, data_type, access="rw", default=None, mappable=False, unit=""):
    var = ODVariable(name, index, subindex)
    var.data_type = getattr(datatypes, data_type)
    var.access_type = access
    var.default = default
    var.pdo_mappable = mappable
    var.unit = unit
    return var


def _record(od, name, index, members, array=False, sub0_access="ro") -> ODRecord | ODArray:
    """Add a record (or array) whose sub 0 is the highest sub-index and return it; members: (sub, name,
    type, ...)."""
    obj = (ODArray if array else ODRecord)(name, index)
    highest = max(m[0] for m in members)
    obj.add_member(_var("Highest sub-index supported", index, 0, "UNSIGNED8", sub0_access, highest))
    for sub, member_name, data_type, *rest in members:
        obj.add_member(_var(member_name, index, sub, data_type, *rest))
    od.add_object(obj)
    return obj


def _add_communication_objects(od: ObjectDictionary, prof: DriveProfile, node_id: int) -> None:
    access = prof.communication_access
    od.add_object(_var("Device type", 0x1000, 0, "UNSIGNED32", "ro", 0x00020192))
    od.add_object(_var("Error register", 0x1001, 0, "UNSIGNED8", "ro", 0))
    errors = ODArray("Pre-defined error field", 0x1003)
    # sub 0 = number of errors (write 0 to clear); sub 1 = newest error
    errors.add_member(_var("Number of errors", 0x1003, 0, "UNSIGNED8", "rw", 0))
    for sub in range(1, prof.error_history + 1):
        errors.add_member(_var(f"Standard error field {sub}", 0x1003, sub, "UNSIGNED32", "ro", 0))
    od.add_object(errors)
    od.add_object(_var("COB-ID SYNC", 0x1005, 0, "UNSIGNED32", access[0x1005], SYNC_COB_ID))
    od.add_object(_var("Manufacturer device name", 0x1008, 0, "VISIBLE_STRING", access[0x1008], prof.device_name))
    od.add_object(_var("COB-ID EMCY", 0x1014, 0, "UNSIGNED32", access[0x1014], EMCY_COB_BASE + node_id))
    _record(od, "Consumer heartbeat time", 0x1016, [
        (1, "Consumer heartbeat time 1", "UNSIGNED32", "rw", 0),
        (2, "Consumer heartbeat time 2", "UNSIGNED32", "rw", 0),
    ], array=True)
    od.add_object(_var("Producer heartbeat time", 0x1017, 0, "UNSIGNED16", "rw", 0, unit="ms"))
    _record(od, "Identity object", 0x1018, [
        (1, "Vendor-ID", "UNSIGNED32", "ro", VENDOR_ID_MAXON),
        (2, "Product code", "UNSIGNED32", "ro", prof.product_code),
        (3, "Revision number", "UNSIGNED32", "ro", prof.revision_number),
        (4, "Serial number", "UNSIGNED32", "ro", 0x10000000 + node_id),
    ])
    _record(od, "SDO server parameter", 0x1200, [
        (1, "COB-ID client to server", "UNSIGNED32", "ro", 0x600 + node_id),
        (2, "COB-ID server to client", "UNSIGNED32", "ro", 0x580 + node_id),
    ])
    # Default mapping: TPDO1 = statusword (event-driven), RPDO1 = controlword; the rest invalid.
    for n in range(prof.rpdo_count):
        valid = 0 if n == 0 else 1 << 31
        _record(od, f"Receive PDO {n + 1} parameter", 0x1400 + n, [
            (1, "COB-ID used by RPDO", "UNSIGNED32", "rw", valid | pdo_cob_id("rpdo", n + 1, node_id)),
            (2, "Transmission type", "UNSIGNED8", "rw", 255),
        ] + ([(5, "Event timer", "UNSIGNED16", "rw", 0, False, "ms")]   # deadline monitoring, 0 = off
             if prof.pdo_event_timer else []))
        mapping = _record(od, f"Receive PDO {n + 1} mapping", 0x1600 + n, [
            (sub, f"Mapped object {sub}", "UNSIGNED32", "rw", 0x60400010 if (n, sub) == (0, 1) else 0)
            for sub in range(1, 9)
        ], sub0_access="rw")
        mapping[0].default = 1 if n == 0 else 0
    for n in range(prof.tpdo_count):
        valid = 0 if n == 0 else 1 << 31
        _record(od, f"Transmit PDO {n + 1} parameter", 0x1800 + n, [
            (1, "COB-ID used by TPDO", "UNSIGNED32", "rw", valid | pdo_cob_id("tpdo", n + 1, node_id)),
            (2, "Transmission type", "UNSIGNED8", "rw", 255),
            (3, "Inhibit time", "UNSIGNED16", "rw", 10, False, "100us"),     # 1 ms on both generations
        ] + ([(5, "Event timer", "UNSIGNED16", "rw", 0, False, "ms")] if prof.pdo_event_timer else []))
        mapping = _record(od, f"Transmit PDO {n + 1} mapping", 0x1A00 + n, [
            (sub, f"Mapped object {sub}", "UNSIGNED32", "rw", 0x60410010 if (n, sub) == (0, 1) else 0)
            for sub in range(1, 9)
        ], sub0_access="rw")
        mapping[0].default = 1 if n == 0 else 0


def _add_drive_objects(od: ObjectDictionary, prof: DriveProfile) -> None:
    """The drive's objects: those of the profile (each where the profile says it is; a plain
    variable unless it is part of a record added below) and the generation's own records.
    "rww": written by SDO or by an RPDO (maxon's files say so of every PDO-mappable setting)."""
    mode_bits = sum(1 << _MODE_BITS[mode] for mode in prof.supported_modes)
    for name, ref, access, default, mappable in _plain_objects(prof):
        if ref is not None and ref.subindex == 0 and ref.index not in od:
            od.add_object(_var(name, ref.index, ref.subindex, ref.data_type, access, default, mappable, ref.unit))
    od.add_object(_var("Motion profile type", 0x6086, 0, "INTEGER16", "rww", 0, True))
    od.add_object(_var("Supported drive modes", 0x6502, 0, "UNSIGNED32", "ro", mode_bits))
    lo, hi = prof.software_position_limit
    _record(od, "Software position limit", lo.index, [
        (lo.subindex, "Min position limit", lo.data_type, "rw", -2147483648, False, lo.unit),
        (hi.subindex, "Max position limit", hi.data_type, "rw", 2147483647, False, hi.unit),
    ], array=True, sub0_access="const")
    search, zero = prof.homing_speeds
    _record(od, "Homing speeds", search.index, [
        (search.subindex, "Speed for switch search", search.data_type, "rww", 100, True, search.unit),
        (zero.subindex, "Speed for zero search", zero.data_type, "rww", 10, True, zero.unit),
    ], array=True, sub0_access="const")
    if prof.name == "EPOS2":
        _add_epos2_objects(od, prof)
    else:
        _add_epos4_objects(od, prof)


def _plain_objects(prof: DriveProfile) -> list[tuple]:
    """The profile's objects added as plain variables (each where the profile places it), in the
    order they are added."""
    return [
        # (name, ref, access, default, pdo-mappable); None: the generation has no such object
        ("Error code", prof.error_code, "ro", 0, True),
        ("Controlword", prof.controlword, "rww", 0, True),
        ("Statusword", prof.statusword, "ro", 0, True),
        ("Modes of operation", prof.modes_of_operation, "rww", MODE_PPM, True),
        ("Modes of operation display", prof.modes_display, "ro", MODE_PPM, True),
        ("Position demand value", prof.position_demand, "ro", 0, True),
        ("Position actual value", prof.position_actual, "ro", 0, True),
        ("Following error window", prof.following_error_window, "rww", 2000, True),
        ("Velocity actual value", prof.velocity_actual, "ro", 0, True),
        ("Target position", prof.target_position, "rww", 0, True),
        ("Home position", prof.home_position, "rww", 0, True),
        ("Profile velocity", prof.profile_velocity, "rww", 1000, True),
        ("Profile acceleration", prof.profile_acceleration, "rww", 10000, True),
        ("Profile deceleration", prof.profile_deceleration, "rww", 10000, True),
        ("Quick stop deceleration", prof.quick_stop_deceleration, "rww", 10000, True),
        ("Quick stop option code", prof.quick_stop_option_code, "rw", 2, False),
        ("Homing method", prof.homing_method, "rww", 7, True),
        ("Homing acceleration", prof.homing_acceleration, "rww", 1000, True),
        ("Following error actual value", prof.following_error_actual, "ro", 0, True),
        ("Current actual value", prof.current_actual, "ro", 0, True),
        ("Current actual value averaged", prof.current_averaged, "ro", 0, True),
        ("Position mode setting value", prof.cyclic_target, "rww", 0, True),
    ]


def _add_epos2_objects(od: ObjectDictionary, prof: DriveProfile) -> None:
    """The EPOS2's own objects: motor data, home offset, max profile velocity."""
    # maxon's EDS of the EPOS2 70/10 (firmware 0x2126): its power-up values
    _record(od, "Motor data", 0x6410, [
        (1, "Continuous current limit", "UNSIGNED16", "rww", 10000, True, "mA"),
        (2, "Output current limit", "UNSIGNED16", "rww", 25000, True, "mA"),
        (3, "Pole pair number", "UNSIGNED8", "rw", 1),
        (4, "Maximal motor speed", "UNSIGNED32", "rww", 25000, True, "rpm"),
        (5, "Thermal time constant winding", "UNSIGNED16", "rw", 40, False, "0.1s"),
    ], sub0_access="const")
    od.add_object(_var("Home offset", prof.home_offset.index, 0, "INTEGER32", "rww", 0, True, "qc"))
    od.add_object(_var("Max profile velocity", prof.max_profile_velocity.index, 0, "UNSIGNED32", "rw", 25000,
                       False, "rpm"))


def _add_epos4_objects(od: ObjectDictionary, prof: DriveProfile) -> None:
    """The objects of every other generation (the EPOS4's): motor data, averaged and
    instantaneous current, interpolation period, max motor speed, home offset move distance,
    max profile velocity."""
    _record(od, "Motor data", 0x3001, [
        (1, "Nominal current", "UNSIGNED32", "rw", 5000, False, "mA"),
        (2, "Output current limit", "UNSIGNED32", "rw", 10000, False, "mA"),
        (3, "Number of pole pairs", "UNSIGNED8", "rw", 1),
        (4, "Thermal time constant winding", "UNSIGNED16", "rw", 40, False, "0.1s"),
        (5, "Torque constant", "UNSIGNED32", "rw", 30200, False, "uNm/A"),
    ])
    _record(od, "Current actual values", 0x30D1, [
        (1, "Current actual value averaged", "INTEGER32", "ro", 0, True, "mA"),
        (2, "Current actual value", "INTEGER32", "ro", 0, True, "mA"),
    ])
    _record(od, "Interpolation time period", 0x60C2, [
        (1, "Interpolation time period value", "UNSIGNED8", "rw", 1, False, "ms"),
        (2, "Interpolation time index", "INTEGER8", "rw", -3),
    ])
    od.add_object(_var("Max motor speed", 0x6080, 0, "UNSIGNED32", "rw", 25000, False, "rpm"))
    od.add_object(_var("Home offset move distance", prof.home_offset.index, 0, "INTEGER32", "rw", 0, False,
                       "qc"))
    od.add_object(_var("Max profile velocity", prof.max_profile_velocity.index, 0, "UNSIGNED32", "rw", 10000,
                       False, "rpm"))


def find_variable(od: ObjectDictionary, index: int, subindex: int = 0) -> Optional[ODVariable]:
    """The variable ``index:subindex`` if the dictionary defines it, else ``None``.

    Unlike ``ObjectDictionary.get_variable``, a sub-index an array does not define is absent
    (canopen makes one up from the array's first entry), as it is on the drive.
    """
    obj = od.get(index)
    if isinstance(obj, ODVariable):
        return obj if subindex == 0 else None
    if isinstance(obj, (ODRecord, ODArray)):
        return obj.subindices.get(subindex)
    return None


def make_object_dictionary(profile_name: str | DriveProfile, node_id: int) -> ObjectDictionary:
    """Build the object dictionary of one EPOS2/EPOS4 drive with node-ID ``node_id`` (1..127)
    (``profile_name``: as for :func:`get_profile`).

    Raises:
        ValueError: unknown profile name or a node-ID out of range.
    """
    prof = get_profile(profile_name)
    if not is_node_id(node_id):
        raise ValueError(f"CANopen node-ID must be an integer in 1..127, got {node_id!r}")
    od = ObjectDictionary()
    od.node_id = node_id
    od.device_information.vendor_number = VENDOR_ID_MAXON
    od.device_information.vendor_name = "maxon motor ag"
    od.device_information.product_name = prof.device_name
    od.device_information.product_number = prof.product_code
    _add_communication_objects(od, prof, node_id)
    _add_drive_objects(od, prof)
    return od
