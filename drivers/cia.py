"""The CANopen facts the master and the emulated drives share, written once: CiA 301
communication (COB-IDs, NMT) and the CiA 402 drive profile (statusword and controlword bits,
modes, the state a statusword shows). Where canopen has them (``State402``), they come from it.
"""

from __future__ import annotations

from canopen.profiles.p402 import State402

# -- CiA 301 -----------------------------------------------------------------------------------------
#: the node-IDs a CANopen device may have
NODE_ID_MIN, NODE_ID_MAX = 1, 127


def is_node_id(value) -> bool:
    """``value`` is an integer node-ID in 1..127."""
    return isinstance(value, int) and not isinstance(value, bool) and NODE_ID_MIN <= value <= NODE_ID_MAX


#: COB-ID of the SYNC frame (object 0x1005 default)
SYNC_COB_ID = 0x080
#: EMCY COB-ID is this plus the node-ID (object 0x1014 default)
EMCY_COB_BASE = 0x080
#: NMT command specifier "enter PRE-OPERATIONAL" (a STOPPED node answers no SDO)
NMT_ENTER_PRE_OPERATIONAL = 0x80
#: NMT states as a heartbeat's state byte
NMT_OPERATIONAL, NMT_STOPPED = 0x05, 0x04
#: consumer heartbeat time, sub-index 1: ``node-ID << 16 | time in ms``
HEARTBEAT_CONSUMER = (0x1016, 1)
#: error register, pre-defined error field (history), EMCY COB-ID objects
ERROR_REGISTER, ERROR_HISTORY, EMCY_COB_ID = 0x1001, 0x1003, 0x1014
#: first communication / mapping parameter object of the RPDOs and TPDOs (+ n for PDO n + 1)
RPDO_COMM, RPDO_MAP, TPDO_COMM, TPDO_MAP = 0x1400, 0x1600, 0x1800, 0x1A00


def pdo_cob_id(direction: str, number: int, node_id: int) -> int:
    """Default COB-ID of TPDO/RPDO ``number`` (1..4) of a node: 0x180/0x200 + 0x100 (n − 1) + id."""
    if direction not in ("tpdo", "rpdo") or not 1 <= number <= 4:
        raise ValueError(f"no default COB-ID for {direction} {number}")
    return (0x180 if direction == "tpdo" else 0x200) + 0x100 * (number - 1) + node_id


# -- CiA 402 -----------------------------------------------------------------------------------------
#: statusword bits beside the state bits
SW_FAULT = 0x0008               # bit 3
SW_VOLTAGE_ENABLED = 0x0010     # bit 4
SW_REMOTE = 0x0200              # bit 9
SW_TARGET_REACHED = 0x0400      # bit 10
SW_BIT12 = 0x1000               # PPM set-point acknowledge, HMM homing attained, CSP "drive follows"
SW_BIT13 = 0x2000               # following error (PPM, CSP), homing error (HMM)
SW_HOMED = 0x8000               # maxon: position referenced to home
#: controlword bits beside the state commands
CW_ENABLE_OPERATION = State402.CW_OPERATION_ENABLED   # 0x000F
CW_NEW_SETPOINT = 0x0010        # PPM bit 4; HMM "homing operation start"
CW_CHANGE_IMMEDIATELY = 0x0020  # PPM bit 5
CW_RELATIVE = 0x0040            # PPM bit 6
CW_FAULT_RESET = 0x0080
CW_HALT = 0x0100
#: error code of the present error (a drive may lack it: the EPOS2 has none)
ERROR_CODE = 0x603F
#: modes of operation (0x6060)
MODE_PPM, MODE_HMM = 1, 6
#: (mask, value) of the statusword per state name (canopen's table)
STATE_MASKS = State402.SW_MASK
#: the CiA 402 state names (canopen's ``State402`` names, the keys of :data:`STATE_MASKS`)
NOT_READY, DISABLED, READY, SWITCHED_ON, ENABLED, QUICK_STOP, FAULT_REACTION, FAULT = (
    "NOT READY TO SWITCH ON", "SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON",
    "OPERATION ENABLED", "QUICK STOP ACTIVE", "FAULT REACTION ACTIVE", "FAULT")
#: the states of a drive whose power stage is off and that shows no fault
UNPOWERED = (NOT_READY, DISABLED, READY)
#: the states of a fault (its reaction included)
FAULTED = (FAULT_REACTION, FAULT)


def state_of(statusword: int) -> str:
    """The CiA 402 state name a statusword shows (``UNKNOWN`` if none)."""
    return next((name for name, (mask, value) in STATE_MASKS.items() if statusword & mask == value), "UNKNOWN")


def state_bits(state: str) -> int:
    """The statusword bits of a state (what a drive in it reports)."""
    return STATE_MASKS[state][1]
