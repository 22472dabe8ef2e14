"""The built-in EPOS4 object dictionary against maxon's own, and what the master writes to a drive.

maxon publishes the EPOS4's object dictionary as an EDS ("EPOS4 ... firmware 0x0110") and
writes DCF files of configured drives ("EPOS4 50/15, firmware 0x0170"). Set
``IDENT_HW_MAXON_REFERENCE`` to a folder holding them (``*.eds``, ``*.dcf``) to compare object by
object; without it that test is skipped. The facts the master depends on are also written out
below from those files, so that the bring-up check runs everywhere. The EPOS2's dictionary against
maxon's EPOS2 files: ``tests/test_real_od_epos2.py``.
"""

import dataclasses
from contextlib import contextmanager
import itertools
import os
from pathlib import Path

import can
import canopen
import numpy as np
import pytest

from drivers.bus import BusConfig, open_network
from drivers.epos import DriveGroup
from drivers.sim.lockstep import LockstepSync
from drivers.errors import ConfigError
from drivers.profiles import make_object_dictionary
from drivers.sim import SimulatedRig
from ident_hw.config import load_config, to_model
from ident_hw.experiment.plan import robot_model
from ident_hw.config.to_drivers import axis_config

CONFIG = load_config(Path(__file__).resolve().parent.parent / "configs" / "sim-3prrr.yaml")
PERIOD = 0.004
_channels = itertools.count()

#: objects maxon's EPOS4 EDS (firmware 0x0110) and DCF (firmware 0x0170) do not have
ABSENT_ON_EPOS4 = {(0x1006, 0), (0x1009, 0), (0x100A, 0)} | {(base + n, 5) for base in (0x1400, 0x1800)
                                                            for n in range(4)}
#: objects both files give as not writable
READ_ONLY_ON_EPOS4 = {(0x1005, 0), (0x1014, 0), (0x1018, 1), (0x1018, 2)}


def _variables(od: canopen.ObjectDictionary) -> dict:
    out = {}
    for obj in od.values():
        if isinstance(obj, canopen.objectdictionary.ODVariable):
            out[(obj.index, 0)] = obj
        else:
            for sub in obj.values():
                out[(obj.index, sub.subindex)] = sub
    return out


def _writable(var) -> bool:
    return var.access_type in ("rw", "wo", "rww", "rwr")


def _maxon_files() -> list[Path]:
    folder = os.environ.get("IDENT_HW_MAXON_REFERENCE")
    if not folder:
        pytest.skip("IDENT_HW_MAXON_REFERENCE (a folder with maxon's EPOS4 EDS/DCF) not set")
    files = sorted(p for p in Path(folder).iterdir() if p.suffix.lower() in (".eds", ".dcf") and "epos4" in p.name.lower())
    if not files:
        pytest.skip(f"no EPOS4 .eds/.dcf in {folder}")
    return files


def test_builtin_epos4_dictionary_agrees_with_maxons_files():
    """Every object the project defines exists in maxon's EDS or DCF with the same data type, and
    none the project may write is read-only there (the newer DCF adds ``0x60C2``, the CSP
    interpolation period, which the older EDS lacks; the two files disagree on the type of
    ``0x6086``, INTEGER16 in the DCF: either file's word is taken)."""
    references = [_variables(canopen.import_od(str(path), node_id=1)) for path in _maxon_files()]
    ours = _variables(make_object_dictionary("epos4", 1))
    problems = []
    for key, var in sorted(ours.items()):
        theirs = [ref[key] for ref in references if key in ref]
        name = f"0x{key[0]:04X}:{key[1]:02X} {var.name!r}"
        if not theirs:
            problems.append(f"{name}: in none of maxon's files")
        elif all(t.data_type != var.data_type for t in theirs):
            problems.append(f"{name}: type 0x{var.data_type:X}, maxon 0x{theirs[0].data_type:X}")
        elif _writable(var) and not any(_writable(t) for t in theirs):
            problems.append(f"{name}: writable here, {theirs[0].access_type} on the drive")
    assert problems == []
    # and the facts written out above are what the files say
    for key in ABSENT_ON_EPOS4:
        assert all(key not in ref for ref in references), key
    for key in READ_ONLY_ON_EPOS4:
        assert all(not _writable(ref[key]) for ref in references if key in ref), key


class SdoTraffic(can.Listener):
    """Every SDO request naming an object, as (node-ID, "upload" | "download", index, sub-index),
    and every SDO abort a node answered."""

    def __init__(self):
        self.requests, self.aborts = [], []

    def on_message_received(self, msg):
        cob, data = msg.arbitration_id, msg.data
        if 0x601 <= cob <= 0x67F and msg.dlc == 8 and data[0] & 0xE0 in (0x20, 0x40):
            self.requests.append((cob - 0x600, "download" if data[0] & 0xE0 == 0x20 else "upload",
                                  data[1] | data[2] << 8, data[3]))
        elif 0x581 <= cob <= 0x5FF and msg.dlc == 8 and data[0] == 0x80:
            self.aborts.append((cob - 0x580, data[1] | data[2] << 8, data[3], int.from_bytes(data[4:8], "little")))


@contextmanager
def spied_rig(axes, name: str):
    """Emulated drives for ``axes`` in lockstep (the sim config's robot and truth), a master's
    :class:`DriveGroup` on them (not brought up) and a :class:`SdoTraffic` spy, all on one fresh
    python-can virtual channel named after ``name``; yields ``(rig, group, spy)`` and closes all."""
    channel = f"{name}-{next(_channels)}"
    rig = SimulatedRig.build(robot_model(CONFIG), to_model.inertial_params(CONFIG.sim.truth),
                             [(a.node_id, a.profile, a.scaling) for a in axes], sync_period=PERIOD, seed=1,
                             lockstep=True, interface="virtual", channel=channel, ignore_config=True).start()
    spy_bus = can.Bus(interface="virtual", channel=channel, ignore_config=True)
    spy = SdoTraffic()
    notifier = can.Notifier(spy_bus, [spy])
    network = open_network(BusConfig("virtual", channel, ignore_config=True))
    group = DriveGroup(network, axes, sync=LockstepSync(PERIOD))
    try:
        yield rig, group, spy
    finally:
        group.close()
        network.disconnect()
        notifier.stop()
        spy_bus.shutdown()
        rig.stop()


def test_the_master_writes_only_objects_a_real_epos4_has(tmp_path):
    """Bring-up, homing, a cyclic stream and the stop of six EPOS4 drives: every object written
    over SDO exists in the dictionary (checked against maxon's above) and is writable there, and
    none is one maxon's files say an EPOS4 lacks or keeps read-only (a real drive would abort)."""
    axes = [dataclasses.replace(axis_config(a), profile="epos4") for a in CONFIG.robot.actuators]
    with spied_rig(axes, "real-od") as (_, group, spy):
        group.bring_up()
        group.home()
        start = group.positions()
        t = np.arange(100) * PERIOD
        rec = group.run_cyclic(start + np.sin(2 * np.pi * t)[:, None] * 1e-3, PERIOD)
        assert rec.n_invalid == 0
    ours = _variables(make_object_dictionary("epos4", 1))
    written = sorted(set((index, sub) for _, kind, index, sub in spy.requests if kind == "download"))
    assert len(written) > 20, written      # the spy saw the bring-up
    bad = [f"0x{i:04X}:{s:02X}" for i, s in written
           if (i, s) in ABSENT_ON_EPOS4 or (i, s) in READ_ONLY_ON_EPOS4 or (i, s) not in ours
           or not _writable(ours[(i, s)])]
    assert bad == []


def _exported_eds(tmp_path: Path, node_id: int, without: tuple[int, int] | None = None) -> Path:
    """The built-in EPOS4 dictionary written as an EDS by canopen (a stand-in for a drive's own
    file), optionally without one sub-object."""
    od = make_object_dictionary("epos4", node_id)
    if without is not None:
        record = od[without[0]]
        del record.subindices[without[1]]
        record.names.pop(next(n for n, v in record.names.items() if v.subindex == without[1]), None)
    path = tmp_path / f"node{node_id}.eds"
    canopen.objectdictionary.export_od(od, str(path), doc_type="eds")
    return path


def test_the_master_uses_the_drives_own_eds_and_names_what_it_lacks(tmp_path):
    """``object_dictionary`` of an axis: the master's dictionary comes from that EDS/DCF (a run
    works on it); a file without an object the master needs is refused when the drives are set
    up, before anything moves, naming the node, the file and the object."""
    axes = [dataclasses.replace(axis_config(a), profile="epos4") for a in CONFIG.robot.actuators]
    own = [dataclasses.replace(a, object_dictionary=str(_exported_eds(tmp_path, a.node_id))) for a in axes]
    channel = f"real-od-{next(_channels)}"
    rig = SimulatedRig.build(robot_model(CONFIG), to_model.inertial_params(CONFIG.sim.truth),
                             [(a.node_id, a.profile, a.scaling) for a in axes], sync_period=PERIOD,
                             lockstep=True, interface="virtual", channel=channel, ignore_config=True).start()
    network = open_network(BusConfig("virtual", channel, ignore_config=True))
    try:
        group = DriveGroup(network, own, sync=LockstepSync(PERIOD))
        group.bring_up()
        rec = group.run_cyclic(np.repeat(group.positions()[None], 20, axis=0), PERIOD)
        assert rec.n_invalid == 0
        group.close()
        lacking = dataclasses.replace(axes[4], object_dictionary=str(_exported_eds(tmp_path, axes[4].node_id,
                                                                                   without=(0x30D1, 2))))
        with pytest.raises(ConfigError, match=rf"node {axes[4].node_id} \(zeta2\).*node{axes[4].node_id}\.eds: "
                                              r"EPOS4 firmware 0x0170 \(the file\) lacks 0x30D1:02"):
            DriveGroup(network, axes[:4] + [lacking] + axes[5:], sync=LockstepSync(PERIOD))
    finally:
        network.disconnect()
        rig.stop()


def test_a_configs_object_dictionary_is_relative_to_the_config_file(tmp_path):
    actuator = dataclasses.replace(CONFIG.robot.actuators[3], object_dictionary="drives/zeta1.dcf")
    assert axis_config(actuator, tmp_path).object_dictionary == str(tmp_path / "drives" / "zeta1.dcf")


def _maxon_file(name: str) -> Path:
    folder = os.environ.get("IDENT_HW_MAXON_REFERENCE")
    if not folder or not (Path(folder) / name).is_file():
        pytest.skip(f"IDENT_HW_MAXON_REFERENCE (a folder with maxon's {name}) not set")
    return Path(folder) / name


def test_a_drive_whose_firmware_lacks_an_object_the_run_needs_is_refused_at_bring_up():
    """An EPOS4 whose dictionary is maxon's EDS of firmware 0x0110, which has no interpolation
    period 0x60C2 (the cyclic stream writes it): the master asks each drive for the objects the run
    uses and refuses that one at bring-up, naming the node, its firmware and the object, before any
    drive is enabled. For homing only (``ident-hw home``) it needs nothing the drive lacks: brought up
    and homed."""
    from drivers.errors import BringUpError
    eds = _maxon_file("EPOS4_0110h_6551h.eds")
    axes = [dataclasses.replace(axis_config(a), profile="epos4") for a in CONFIG.robot.actuators]
    channel = f"real-od-{next(_channels)}"
    rig = SimulatedRig.build(robot_model(CONFIG), to_model.inertial_params(CONFIG.sim.truth),
                             [(a.node_id, a.profile, a.scaling) for a in axes], sync_period=PERIOD,
                             lockstep=True, interface="virtual", channel=channel, ignore_config=True,
                             dictionaries={5: eds}).start()
    network = open_network(BusConfig("virtual", channel, ignore_config=True))
    try:
        start = rig.plant.Theta.copy()
        group = DriveGroup(network, axes, sync=LockstepSync(PERIOD))
        with pytest.raises(BringUpError, match=r"node 5 \(zeta2\): EPOS4 firmware 0x0110 lacks 0x60C2:01 "
                                               r"\(interpolation time period \(the cyclic stream writes it: CSP\)\); "
                                               r"0x60C2:02 .*maxon.s EDS of the EPOS4 for firmware 0x0110 has no 0x60C2 either.*update the drive.s firmware\); nothing has moved"):
            group.bring_up()
        assert all(d.state == "SWITCH ON DISABLED" for d in rig.drives)
        np.testing.assert_array_equal(rig.plant.Theta, start)
        group.close()
        homing = DriveGroup(network, axes, sync=LockstepSync(PERIOD), uses=("bring_up", "home"))
        homing.bring_up()
        homing.home()
        homing.close()
    finally:
        network.disconnect()
        rig.stop()


def test_maxons_older_eds_is_accepted_as_a_drive_dictionary_where_the_command_needs_nothing_it_lacks():
    """The same EDS as the master's dictionary of an axis (``object_dictionary``): refused for a run
    (its file lacks 0x60C2), accepted for homing; ``check`` says both."""
    from drivers.firmware import load_object_dictionary
    from ident_hw.experiment.plan import dictionary_problems
    eds = _maxon_file("EPOS4_0110h_6551h.eds")
    with pytest.raises(ValueError, match=r"EPOS4_0110h_6551h\.eds: EPOS4 firmware 0x0110 \(the file\) lacks 0x60C2:01"):
        load_object_dictionary(eds, "epos4", 4)
    od = load_object_dictionary(eds, "epos4", 4, uses=("bring_up", "home"))
    assert 0x60C2 not in od and od[0x1018][3].default == 0x01100000
    hil = load_config(Path(__file__).resolve().parent.parent / "configs" / "hil-3prrr-epos4.yaml")
    actuators = list(hil.robot.actuators)
    actuators[3] = dataclasses.replace(actuators[3], object_dictionary=str(eds))
    config = dataclasses.replace(hil, robot=dataclasses.replace(hil.robot, actuators=tuple(actuators)))
    problems = dictionary_problems(config)
    assert len(problems) == 1 and problems[0].startswith("node 4 (zeta1): object dictionary") and \
        "lacks 0x60C2:01" in problems[0] and "`ident-hw home` works on it" in problems[0], problems


def test_the_firmware_gaps_agree_with_maxons_files():
    """What the EPOS4 profile says an older firmware lacks is what maxon's files show: the EDS of
    firmware 0x0110 lacks exactly those of the objects a run uses, the DCF of 0x0170 has them all."""
    from drivers.firmware import objects_used
    from drivers.profiles import EPOS4, find_variable
    eds = canopen.import_od(str(_maxon_file("EPOS4_0110h_6551h.eds")), 1)
    dcf = canopen.import_od(str(_maxon_file("epos4_50_15_fw0170_node1.dcf")), 1)
    (gap,) = EPOS4.firmware_gaps
    for current in ("instantaneous", "averaged"):
        used = objects_used(EPOS4, current)
        assert sorted(k for k in used if find_variable(eds, *k) is None) == sorted(gap.lacks)
        assert [k for k in used if find_variable(dcf, *k) is None] == []
    assert eds[0x1018][3].default >> 16 == gap.known_without
    assert dcf[0x1018][3].value >> 16 == gap.known_with
