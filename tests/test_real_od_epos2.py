"""The built-in EPOS2 object dictionary against maxon's own, what the master reads and writes on an
EPOS2, and what an emulated EPOS2 answers about the objects it does not have.

maxon publishes the EPOS2 70/10's object dictionary as an EDS (firmware 0x2126), and EPOS Studio
exports a DCF from a drive (the EDS's objects with the values read from it). Set
``IDENT_HW_MAXON_REFERENCE`` to a folder holding them (``*.eds``, ``*.dcf`` with "epos2" in the
name) to compare object by object; without it that test is skipped. The facts the master depends
on are also written out below from those files (:data:`EPOS2_FACTS`, :data:`ABSENT_ON_EPOS2`), so
that the other tests run everywhere, and the comparison checks them against the files too.
"""

import dataclasses
import os
from pathlib import Path

import canopen
import numpy as np
import pytest
from canopen.sdo import SdoAbortedError

from drivers.errors import DriveFault
from drivers.firmware import objects_used
from drivers.profiles import EPOS2, find_variable, make_object_dictionary
from ident_hw.config import load_config

from test_real_od import PERIOD, _variables, _writable, spied_rig
from test_sim_rig import Bench
from ident_hw.config.to_drivers import axis_config

CONFIG = load_config(Path(__file__).resolve().parent.parent / "configs" / "sim-3prrr.yaml")

ABORT_NO_OBJECT, ABORT_NO_SUBINDEX = 0x06020000, 0x06090011

#: the objects the master uses on an EPOS2 (and those the issue names): data type, access,
#: PDO-mappable, as maxon's EDS of the EPOS2 70/10 (firmware 0x2126) and the DCF give them
EPOS2_FACTS = {
    (0x1001, 0): ("UNSIGNED8", "ro", False),          # error register: an error is present
    (0x1003, 0): ("UNSIGNED8", "rw", False),          # number of errors (0 clears the history)
    (0x1003, 1): ("UNSIGNED32", "ro", False),         # newest error: the code of a fault (no 0x603F)
    (0x1005, 0): ("UNSIGNED32", "rw", False),         # SYNC COB-ID: writable (const on the EPOS4)
    (0x1008, 0): ("VISIBLE_STRING", "const", False),  # device name
    (0x1014, 0): ("UNSIGNED32", "rw", False),         # EMCY COB-ID: writable (ro on the EPOS4)
    (0x1016, 1): ("UNSIGNED32", "rw", False),         # consumer heartbeat time (the master's)
    (0x1017, 0): ("UNSIGNED16", "rw", False),         # producer heartbeat time
    (0x1018, 1): ("UNSIGNED32", "ro", False),         # vendor-ID
    (0x1018, 2): ("UNSIGNED32", "ro", False),         # product code
    (0x1018, 3): ("UNSIGNED32", "ro", False),         # revision number: the firmware in its upper 16 bits
    (0x2027, 0): ("INTEGER16", "ro", True),           # current actual value averaged, mA
    (0x2062, 0): ("INTEGER32", "rww", True),          # position mode setting value (mode -1)
    (0x2081, 0): ("INTEGER32", "rww", True),          # home position
    (0x20F4, 0): ("INTEGER16", "ro", True),           # following error actual value (no 0x60F4)
    (0x6040, 0): ("UNSIGNED16", "rww", True),         # controlword
    (0x6041, 0): ("UNSIGNED16", "ro", True),          # statusword
    (0x6060, 0): ("INTEGER8", "rww", True),           # modes of operation
    (0x6061, 0): ("INTEGER8", "ro", True),            # modes of operation display
    (0x6062, 0): ("INTEGER32", "ro", True),           # position demand value
    (0x6064, 0): ("INTEGER32", "ro", True),           # position actual value, qc
    (0x6065, 0): ("UNSIGNED32", "rww", True),         # following error window
    (0x606C, 0): ("INTEGER32", "ro", True),           # velocity actual value, rpm
    (0x6078, 0): ("INTEGER16", "ro", True),           # current actual value, mA (16 bits)
    (0x607A, 0): ("INTEGER32", "rww", True),          # target position
    (0x607C, 0): ("INTEGER32", "rww", True),          # home offset
    (0x607D, 1): ("INTEGER32", "rw", False),          # software position limits
    (0x607D, 2): ("INTEGER32", "rw", False),
    (0x607F, 0): ("UNSIGNED32", "rw", False),         # max profile velocity
    (0x6081, 0): ("UNSIGNED32", "rww", True),         # profile velocity, acceleration, deceleration
    (0x6083, 0): ("UNSIGNED32", "rww", True),
    (0x6084, 0): ("UNSIGNED32", "rww", True),
    (0x6085, 0): ("UNSIGNED32", "rww", True),         # quick stop deceleration
    (0x6098, 0): ("INTEGER8", "rww", True),           # homing method, speeds, acceleration
    (0x6099, 1): ("UNSIGNED32", "rww", True),
    (0x6099, 2): ("UNSIGNED32", "rww", True),
    (0x609A, 0): ("UNSIGNED32", "rww", True),
    (0x6410, 2): ("UNSIGNED16", "rww", True),         # output current limit, mA
    **{(base + n, sub): (kind, "rw", False)           # PDO parameters: COB-ID, transmission type
       for base in (0x1400, 0x1800) for n in range(4) for sub, kind in ((1, "UNSIGNED32"), (2, "UNSIGNED8"))},
    **{(base + n, 0): ("UNSIGNED8", "rw", False)      # PDO mappings: number of mapped objects
       for base in (0x1600, 0x1A00) for n in range(4)},
}
#: objects a real EPOS2 does not have (both files): no 0x1006/0x1009/0x100A, five entries of error
#: history, no PDO event timer (sub-index 5), no 0x603F (error code), 0x605A (quick stop option
#: code) or 0x60F4 (following error actual value: 0x20F4), no 0x30D1 (the EPOS4's currents)
ABSENT_ON_EPOS2 = ({(0x1006, 0), (0x1009, 0), (0x100A, 0), (0x603F, 0), (0x605A, 0), (0x60F4, 0), (0x30D1, 1),
                    (0x30D1, 2)} | {(0x1003, sub) for sub in (6, 7, 8)}
                   | {(base + n, 5) for base in (0x1400, 0x1800) for n in range(4)})
#: the power-up PDO configuration (COB-IDs and mappings): the master writes all of it at bring-up,
#: so the defaults here (TPDO1 = statusword, RPDO1 = controlword, the others invalid) need not be
#: maxon's (which map 0x60FF, an object the project does not define)
PDO_SETUP = ({(base + n, 1) for base in (0x1400, 0x1800) for n in range(4)}
             | {(base + n, sub) for base in (0x1600, 0x1A00) for n in range(4) for sub in range(9)})
#: values of the DCF (read from the drive) the dictionary's defaults give too
READ_FROM_THE_DRIVE = ((0x1000, 0), (0x1018, 1), (0x1018, 2), (0x1018, 3), (0x6502, 0))
CSP_BIT = 1 << 7      # 0x6502, CiA 402 "cyclic synchronous position"


def _maxon_epos2_files() -> list[Path]:
    folder = os.environ.get("IDENT_HW_MAXON_REFERENCE")
    if not folder:
        pytest.skip("IDENT_HW_MAXON_REFERENCE (a folder with maxon's EPOS2 EDS/DCF) not set")
    files = sorted(p for p in Path(folder).iterdir()
                   if p.suffix.lower() in (".eds", ".dcf") and "epos2" in p.name.lower())
    if not files:
        pytest.skip(f"no EPOS2 .eds/.dcf in {folder}")
    return files


def _fact(var) -> tuple[str, str, bool]:
    names = {v: k for k, v in vars(canopen.objectdictionary.datatypes).items() if isinstance(v, int) and k.isupper()}
    return names[var.data_type], var.access_type, bool(var.pdo_mappable)


def test_builtin_epos2_dictionary_agrees_with_both_maxon_files():
    """Every object the built-in EPOS2 dictionary defines is in the EDS and in the DCF with the
    same data type, access and PDO mapping; every default the EDS gives is the built-in one (the
    power-up PDO configuration aside, :data:`PDO_SETUP`), and so are the identity and supported
    modes the DCF read from the drive. The facts written out above are what both files say. (Each
    file found is compared: maxon's folder holds both.)"""
    files = _maxon_epos2_files()
    references = {path.name: canopen.import_od(str(path), node_id=1) for path in files}
    ours = _variables(make_object_dictionary("epos2", 1))
    problems = []
    for file_name, od in references.items():
        theirs = _variables(od)
        for key, var in sorted(ours.items()):
            name = f"{file_name}: 0x{key[0]:04X}:{key[1]:02X} {var.name!r}"
            ref = theirs.get(key)
            if ref is None:
                problems.append(f"{name}: not on the drive")
                continue
            if _fact(ref) != _fact(var):
                problems.append(f"{name}: {_fact(var)} here, {_fact(ref)} on the drive")
            if key not in PDO_SETUP and ref.default is not None and ref.default != var.default:
                problems.append(f"{name}: default {var.default!r} here, {ref.default!r} on the drive")
        for key in READ_FROM_THE_DRIVE:
            value = theirs[key].value
            if value is not None and value != ours[key].default:
                problems.append(f"{file_name}: 0x{key[0]:04X}:{key[1]:02X} = {value:#x} on the drive, "
                                f"{ours[key].default:#x} here")
        for key, fact in EPOS2_FACTS.items():
            if key not in theirs or _fact(theirs[key]) != fact:
                problems.append(f"{file_name}: fact 0x{key[0]:04X}:{key[1]:02X} {fact} is not the file's")
        problems += [f"{file_name}: has 0x{i:04X}:{s:02X}" for i, s in sorted(ABSENT_ON_EPOS2) if (i, s) in theirs]
        supported = theirs[(0x6502, 0)].value
        if supported is not None and supported & CSP_BIT:
            problems.append(f"{file_name}: CSP supported")
        name = theirs[(0x1008, 0)].value
        if name is not None and not name.startswith(EPOS2.name):      # the master's identity check
            problems.append(f"{file_name}: device name {name!r}")
    assert problems == []


def test_the_epos2_profile_and_dictionary_hold_the_facts_the_master_depends_on():
    """Runs everywhere: the built-in dictionary has every fact above and none of the absent
    objects; the profile names, for each fact the master needs, the object the EPOS2 has."""
    od = make_object_dictionary("epos2", 1)
    assert {key: _fact(find_variable(od, *key)) for key in EPOS2_FACTS if find_variable(od, *key)} == EPOS2_FACTS
    assert set(objects_used(EPOS2, "instantaneous")) | set(objects_used(EPOS2, "averaged")) <= set(EPOS2_FACTS)
    assert [key for key in sorted(ABSENT_ON_EPOS2) if find_variable(od, *key) is not None] == []
    p = EPOS2
    assert (p.error_code.index, p.error_code.subindex, p.error_code.data_type) == (0x1003, 1, "UNSIGNED32")
    assert (p.following_error_actual.index, p.following_error_actual.data_type) == (0x20F4, "INTEGER16")
    assert (p.current_actual.index, p.current_actual.data_type) == (0x6078, "INTEGER16")
    assert (p.current_averaged.index, p.current_averaged.data_type) == (0x2027, "INTEGER16")
    assert p.quick_stop_option_code is None and not p.pdo_event_timer and p.error_history == 5
    assert 8 not in p.supported_modes and not od[0x6502].default & CSP_BIT


def _epos2_axes():
    """The simulated 3PRRR's axes on six EPOS2 (homing on the actual position: method 35 there)."""
    axes = []
    for a in CONFIG.robot.actuators:
        axis = dataclasses.replace(axis_config(a), profile="epos2")
        if axis.homing is not None:
            axis = dataclasses.replace(axis, homing=dataclasses.replace(axis.homing, method=35))
        axes.append(axis)
    return axes


@pytest.fixture
def epos2_rig():
    """Six emulated EPOS2 in lockstep, a master's :class:`DriveGroup` (not brought up) and a spy
    on the SDO traffic, all on one fresh python-can virtual channel."""
    with spied_rig(_epos2_axes(), "real-od-epos2") as parts:
        yield parts


def _targets(group, n=100, amplitude=1e-3):
    t = np.arange(n) * PERIOD
    return group.positions() + np.sin(2 * np.pi * t)[:, None] * amplitude


def test_the_master_uses_only_objects_a_real_epos2_has(epos2_rig):
    """Bring-up, homing, a cyclic stream, a profile move and the stop of six EPOS2: every object
    read or written over SDO is one the EPOS2 has (the built-in dictionary, checked against maxon's
    files above), none is one it lacks, every write goes to a writable object, and no drive
    aborted a request (the emulated drive aborts what a real one would, see below)."""
    rig, group, spy = epos2_rig
    group.bring_up()
    group.home()
    rec = group.run_cyclic(_targets(group), PERIOD)
    assert rec.n_invalid == 0
    group.move_to(group.positions() + 1e-3)
    assert [d.error_text() for d in group.drives] == ["no error code"] * 6
    group.stop_motion()
    od = make_object_dictionary("epos2", 1)
    used = sorted({(kind, index, sub) for _, kind, index, sub in spy.requests})
    assert len(used) > 30, used                       # the spy saw the bring-up
    bad = [f"{kind} 0x{index:04X}:{sub:02X}" for kind, index, sub in used
           if (index, sub) in ABSENT_ON_EPOS2 or find_variable(od, index, sub) is None
           or (kind == "download" and not _writable(find_variable(od, index, sub)))]
    assert bad == []
    assert spy.aborts == []


def test_an_emulated_epos2_aborts_sdo_access_to_what_a_real_one_lacks():
    """A canopen master on a python-can virtual bus: an upload (or download) of an object the
    EPOS2 does not have is aborted with CiA 301's 0x06020000, of a sub-index it does not have
    with 0x06090011 (also one past the end of an array: canopen's ``LocalNode`` alone would
    answer that with a value made up from the array's first entry); what it has answers."""
    bench = Bench(profiles=("epos2",) * 6)
    try:
        bench.rig.start()
        node = bench.nodes[1]
        cases = [((0x603F, 0), ABORT_NO_OBJECT), ((0x1400, 5), ABORT_NO_SUBINDEX), ((0x1800, 5), ABORT_NO_SUBINDEX),
                 ((0x60F4, 0), ABORT_NO_OBJECT), ((0x605A, 0), ABORT_NO_OBJECT), ((0x1006, 0), ABORT_NO_OBJECT),
                 ((0x1003, 6), ABORT_NO_SUBINDEX), ((0x6041, 1), ABORT_NO_SUBINDEX)]
        for (index, sub), code in cases:
            with pytest.raises(SdoAbortedError) as err:
                node.sdo.upload(index, sub)
            assert err.value.code == code, f"upload 0x{index:04X}:{sub:02X}: 0x{err.value.code:08X}"
        for (index, sub), code in [((0x1400, 5), ABORT_NO_SUBINDEX), ((0x603F, 0), ABORT_NO_OBJECT)]:
            with pytest.raises(SdoAbortedError) as err:
                node.sdo.download(index, sub, b"\x32\x00")
            assert err.value.code == code, f"download 0x{index:04X}:{sub:02X}: 0x{err.value.code:08X}"
        # what it has instead answers: the following error, the averaged current, the newest error
        for index, sub in ((0x20F4, 0), (0x2027, 0), (0x1003, 5), (0x1400, 2)):
            assert len(node.sdo.upload(index, sub)) in (1, 2, 4)
    finally:
        bench.close()


def test_a_fault_of_an_epos2_is_named_with_its_error_code_without_0x603f(epos2_rig):
    """A drive faults with its EMCY switched off (0x1014 bit 31, writable on the EPOS2): the
    master sees only the statusword's fault bit and names the fault by the drive's newest error
    ``0x1003:01`` (never asking for 0x603F, which the EPOS2 lacks). Once the fault is reset the
    drive has no present error (error register 0x1001 = 0) although its history keeps the code.
    (A fault announced by EMCY carries the EMCY's code: ``test_drivers_master.test_emcy_following_error``,
    on an EPOS2 node.)"""
    rig, group, spy = epos2_rig
    group.bring_up()
    group.home()
    drive = group.drives[1]
    drive.write((0x1014, 0), 1 << 31 | 0x80 + drive.axis.node_id)          # no EMCY from this drive
    rig.schedule(50 * PERIOD, lambda: rig.emcy(drive.axis.node_id, 0x2310))
    with pytest.raises(DriveFault) as info:
        group.run_cyclic(_targets(group, 200), PERIOD)
    fault = info.value
    assert fault.code == 0x2310 and drive.label in str(fault) and "Overcurrent error" in str(fault), str(fault)
    assert "statusword" in str(fault)                  # seen by the statusword, not by an EMCY
    assert rig.drive(drive.axis.node_id).state == "FAULT"
    assert drive.fault_code() == 0x2310 and drive.error_text() == "0x2310 Overcurrent error"
    drive.reset_fault()
    assert drive.fault_code() is None and drive.error_text() == "no error code"
    assert drive.read((0x1003, 1)) & 0xFFFF == 0x2310                      # the history keeps it
    asked = {(index, sub) for node, kind, index, sub in spy.requests if kind == "upload"}
    assert (0x1003, 1) in asked and (0x603F, 0) not in asked
    assert spy.aborts == []
