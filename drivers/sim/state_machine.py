"""The CiA 402 power state machine of an emulated drive, as pure functions: the state a
controlword leads to, and the statusword a state shows. The drive (:mod:`drivers.sim.drive`)
keeps the state and acts on the transitions (demand reset, fault reaction, event TPDOs). The state
names are the master's (:mod:`drivers.cia`)."""

from __future__ import annotations

from drivers.cia import (DISABLED, ENABLED, FAULT_REACTION, NOT_READY, QUICK_STOP, READY, SW_HOMED, SW_REMOTE,
                         SW_VOLTAGE_ENABLED, SWITCHED_ON, state_bits)
#: states in which the position loop is closed (also while quick-stopping and during the fault reaction)
POWERED = (ENABLED, QUICK_STOP, FAULT_REACTION)


def next_state(state: str, controlword: int) -> str:
    """The state a device command in ``controlword`` leads to from ``state`` (CiA 402 table of
    the device control commands; the fault reset edge and the FAULT states are the caller's)."""
    cw = controlword
    if cw & 0x02 == 0:                                 # disable voltage
        return DISABLED
    if cw & 0x06 == 0x02:                              # quick stop
        return QUICK_STOP if state == ENABLED else (DISABLED if state in (READY, SWITCHED_ON) else state)
    if cw & 0x07 == 0x06:                              # shutdown
        return READY if state in (DISABLED, SWITCHED_ON, ENABLED) else state
    if cw & 0x0F == 0x07:                              # switch on / disable operation
        return SWITCHED_ON if state in (READY, ENABLED) else state
    if cw & 0x0F == 0x0F:                              # enable operation
        return ENABLED if state in (READY, SWITCHED_ON, QUICK_STOP) else state
    return state


def statusword(state: str, mode_bits: int = 0, homed: bool = False) -> int:
    """The statusword of a drive in ``state``: the state bits, remote, voltage enabled outside
    the first two states, the operating mode's bits (10, 12, 13) while enabled or quick-stopping,
    maxon's "homed" bit 15."""
    sw = state_bits(state) | SW_REMOTE
    if state not in (NOT_READY, DISABLED):
        sw |= SW_VOLTAGE_ENABLED
    if state in (ENABLED, QUICK_STOP):
        sw |= mode_bits
    return sw | (SW_HOMED if homed else 0)
