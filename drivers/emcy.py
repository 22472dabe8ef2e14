"""Readable descriptions of CANopen EMCY / maxon device error codes.

Codes are looked up first in the table of the drive generation (maxon EPOS2 or EPOS4 firmware
specification, "device error codes"), then in the CiA 301/402 codes common to both, and finally
by error class with :class:`canopen.emcy.EmcyError`'s class table ("Current", "Voltage", ...).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from canopen.emcy import EmcyError

# CiA 301 / CiA 402 codes shared by both generations.
COMMON_CODES = MappingProxyType({
    0x0000: "No error / error reset",
    0x1000: "Generic error",
    0x2310: "Overcurrent error",
    0x3210: "Overvoltage error",
    0x3220: "Undervoltage error",
    0x4210: "Overtemperature (thermal overload) error",
    0x5113: "Logic supply voltage too low error",
    0x6320: "Software parameter error",
    0x7320: "Position sensor error",
    0x8110: "CAN overrun error (object lost)",
    0x8111: "CAN overrun error",
    0x8120: "CAN passive mode error",
    0x8130: "CAN heartbeat / life guard error",
    0x8150: "CAN PDO COB-ID collision",
    0x81FD: "CAN bus turned off",
    0x81FE: "CAN Rx queue overflow",
    0x81FF: "CAN Tx queue overflow",
    0x8210: "CAN PDO length error",
    0x8250: "RPDO timeout",   # deadline monitoring, 0x140x:05
    0x8611: "Following error",
})

# maxon EPOS2 firmware specification, device error codes (manufacturer-specific 0xFFxx).
EPOS2_CODES = MappingProxyType({
    0x5114: "Supply voltage (output stage) too low error",
    0x6100: "Internal software error",
    0xFF01: "Hall sensor error",
    0xFF02: "Index processing error",
    0xFF03: "Encoder resolution error",
    0xFF04: "Hall sensor not found error",
    0xFF06: "Negative limit switch error",
    0xFF07: "Positive limit switch error",
    0xFF08: "Hall angle detection error",
    0xFF09: "Software position limit error",
    0xFF0A: "Position sensor breach error",
    0xFF0B: "System overloaded error",
})

# maxon EPOS4 firmware specification, device error codes.
EPOS4_CODES = MappingProxyType({
    0x1080: "Generic initialization error",
    0x1081: "Generic initialization error",
    0x1082: "Generic initialization error",
    0x1083: "Generic initialization error",
    0x1090: "Firmware incompatibility error",
    0x2320: "Power stage protection error",
    0x5280: "Hardware defect error",
    0x5281: "Hardware incompatibility error",
    0x5480: "Hardware error",
    0x5481: "Hardware error",
    0x5482: "Hardware error",
    0x5483: "Hardware error",
    0x6080: "Sign of life error",
    0x6081: "Extension 1 watchdog error",
    0x7380: "Position sensor breach error",
    0x7381: "Position sensor resolution error",
    0x7382: "Position sensor index error",
    0x7388: "Hall sensor error",
    0x7389: "Hall sensor not found error",
    0x738A: "Hall angle detection error",
    0x738C: "SSI sensor error",
    0x7390: "Missing main sensor error",
    0x7391: "Missing commutation sensor error",
    0x7392: "Main sensor direction error",
    0x8A80: "Negative limit switch error",
    0x8A81: "Positive limit switch error",
    0x8A82: "Software position limit error",
    0x8A88: "STO error",
    0xFF01: "System overloaded error",
    0xFF02: "Watchdog error",
    0xFF0B: "System peak overloaded error",
    0xFF10: "Controller gain error",
    0xFF12: "Auto tuning current limit error",
    0xFF13: "Auto tuning identification current error",
    0xFF14: "Auto tuning buffer overflow error",
    0xFF15: "Auto tuning sample mismatch error",
    0xFF16: "Auto tuning parameter error",
    0xFF17: "Auto tuning amplitude mismatch error",
    0xFF18: "Auto tuning period length error",
    0xFF19: "Auto tuning timeout error",
    0xFF20: "Auto tuning standstill error",
    0xFF21: "Auto tuning torque invalid error",
})

_BY_PROFILE = {"EPOS2": EPOS2_CODES, "EPOS4": EPOS4_CODES}


def describe(code: int, profile: str | None = None) -> str:
    """Readable text of an error code, e.g. ``describe(0x8611) == "Following error"``.

    Args:
        code: 16-bit EMCY error code (also the value of 0x603F, or bits 0-15 of 0x1003:01).
        profile: ``"EPOS2"`` or ``"EPOS4"`` (case-insensitive) to resolve the
            manufacturer-specific codes, which differ between the generations.
    """
    table: Mapping[int, str] = _BY_PROFILE.get((profile or "").upper(), {})
    if code in table:
        return table[code]
    if code in COMMON_CODES:
        return COMMON_CODES[code]
    error_class = EmcyError(code, 0, b"", 0.0).get_desc()
    return f"unknown {error_class or 'error'} code" if error_class else "unknown error code"
