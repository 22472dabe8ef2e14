"""The simulated rig against a REAL canopen master on python-can's virtual bus."""

import itertools
import time

import canopen
import numpy as np
import pytest
from canopen.profiles.p402 import BaseNode402
from canopen.sdo import SdoAbortedError

from drivers.bus import NOTIFIER_CYCLE
from drivers.profiles import make_object_dictionary
from drivers.sim import SimulatedRig
import nominal

_channels = itertools.count()
REV, PRI = nominal.REVOLUTE, nominal.PRISMATIC


class Bench:
    """A rig and a canopen master on one fresh virtual channel."""

    def __init__(self, profiles=("epos4",) * 6, node_class=canopen.RemoteNode, **rig_kwargs):
        channel = f"sim-rig-test-{next(_channels)}"
        nodes = [(i + 1, profiles[i], REV if i < 3 else PRI) for i in range(6)]
        self.rig = SimulatedRig.build(nominal.ROBOT, nominal.TRUE_PARAMS, nodes, interface="virtual",
                                      channel=channel, ignore_config=True, **rig_kwargs)
        self.master = canopen.Network()
        self.master.NOTIFIER_CYCLE = NOTIFIER_CYCLE     # a quick disconnect
        self.master.connect(interface="virtual", channel=channel, ignore_config=True)
        self.nodes = []
        self.boot_states = {}
        for d in self.rig.drives:
            node = node_class(d.id, make_object_dictionary(d.profile, d.id))
            self.master.add_node(node)
            node.nmt.add_heartbeat_callback(lambda state, i=d.id: self.boot_states.setdefault(i, state))
            self.nodes.append(node)

    def close(self):
        self.master.sync.stop()
        self.master.disconnect()
        self.rig.stop()


@pytest.fixture
def bench():
    b = Bench()
    yield b
    b.close()


def wait_until(predicate, timeout=2.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.005)
    return predicate()


def test_bootup_heartbeat_identity_and_sdo_errors(bench):
    bench.rig.start()
    assert wait_until(lambda: len(bench.boot_states) == 6)
    assert set(bench.boot_states.values()) == {0}          # boot-up frames
    node = bench.nodes[0]
    node.sdo[0x1017].raw = 20                                # heartbeat producer, 20 ms
    stamp = node.nmt.timestamp
    assert wait_until(lambda: node.nmt.timestamp != stamp) and node.nmt.state == "PRE-OPERATIONAL"
    assert node.sdo[0x1018][1].raw == 0xFB
    assert node.sdo[0x1008].raw == "EPOS4 50/5"
    with pytest.raises(SdoAbortedError) as err:
        node.sdo[0x6064].raw = 5                             # read-only
    assert err.value.code == 0x06010002
    with pytest.raises(SdoAbortedError) as err:
        node.sdo.upload(0x6078, 0)                           # EPOS4 has no 0x6078
    assert err.value.code == 0x06020000
    node.nmt.state = "STOPPED"
    assert wait_until(lambda: node.nmt.state == "STOPPED")


def test_epos2_has_no_30d1():
    b = Bench(profiles=("epos2",) * 6)
    try:
        b.rig.start()
        with pytest.raises(SdoAbortedError) as err:
            b.nodes[2].sdo.upload(0x30D1, 2)
        assert err.value.code == 0x06020000
        assert b.nodes[2].sdo[0x1008].raw == "EPOS2 70/10"
    finally:
        b.close()


def configure_pdos(node, profile_name):
    """TPDO1 = position + current (+ statusword on EPOS2), SYNC; EPOS4 statusword in TPDO2, SYNC."""
    node.tpdo.read()
    node.rpdo.read()
    for pdo in node.tpdo.values():
        pdo.enabled = False
    t1 = node.tpdo[1]
    t1.clear()
    t1.add_variable(0x6064)
    if profile_name == "EPOS2":
        t1.add_variable(0x6078)
        t1.add_variable(0x6041)
    else:
        t1.add_variable(0x30D1, 2)
        t2 = node.tpdo[2]
        t2.clear()
        t2.add_variable(0x6041)
        t2.trans_type, t2.enabled = 1, True        # on SYNC: a real EPOS4 has no TPDO event timer
    t1.trans_type, t1.enabled = 1, True
    r1 = node.rpdo[1]
    r1.clear()
    r1.add_variable(0x607A if profile_name == "EPOS4" else 0x2062)
    r1.add_variable(0x6040)
    r1.trans_type, r1.enabled = 1, True
    for pdo in node.rpdo.values():
        if pdo is not r1:
            pdo.enabled = False
    node.tpdo.save()
    node.rpdo.save()


@pytest.mark.parametrize("profile", ["EPOS2", "EPOS4"])
def test_pdo_mapping_cia402_and_cyclic_following(profile):
    b = Bench(profiles=(profile.lower(),) * 6, node_class=BaseNode402)
    try:
        b.rig.start()
        prof = b.rig.drives[0].profile
        for node in b.nodes:
            configure_pdos(node, profile)
            node.sdo[0x6060].raw = prof.cyclic_mode
            node.setup_402_state_machine(read_pdos=False)
            # the rig and the master share this process (and the GIL): canopen's 0.2-0.8 s defaults
            # are tight for a loaded CI machine
            node.TIMEOUT_CHECK_TPDO, node.TIMEOUT_SWITCH_STATE_SINGLE, node.TIMEOUT_SWITCH_STATE_FINAL = 1.0, 2.0, 4.0
        received = []
        b.nodes[3].tpdo[1].add_callback(lambda m: received.append(m[0x6064].raw))
        b.master.nmt.state = "OPERATIONAL"
        b.master.sync.start(0.004)
        for node in b.nodes:
            node.rpdo[1].start(0.004)
            node.state = "OPERATION ENABLED"
        assert [d.state for d in b.rig.drives] == ["OPERATION ENABLED"] * 6
        assert wait_until(lambda: len(received) > 5)
        # carriage 1 follows a 1 mm step sent as RPDO target
        node, scaling = b.nodes[3], PRI
        target = scaling.counts_from_position(0.001)
        target_var = node.rpdo[1][0]
        for k in range(1, 101):   # ramp over 0.4 s
            target_var.raw = round(target * k / 100)
            time.sleep(0.004)
        assert wait_until(lambda: abs(received[-1] - target) < 0.02 * target, timeout=1.0), received[-5:]
        # the others held their home position (encoders read 0 at power-up)
        assert abs(b.nodes[4].sdo[0x6064].raw) < 0.02 * target
        # fault: EMCY seen by the master with its code, statusword FAULT, fault reset
        b.rig.emcy(4, 0x2310)
        emcy = node.emcy.wait(0x2310, timeout=1.0)
        assert emcy is not None and emcy.register & 0x02
        assert wait_until(lambda: node.state == "FAULT")
        assert node.sdo[0x1003][1].raw == 0x2310 and node.sdo[0x1001].raw & 0x02
        if profile == "EPOS4":                                          # the EPOS2 has no 0x603F
            assert node.sdo[0x603F].raw == 0x2310
        node.state = "OPERATION ENABLED"        # canopen: fault reset (0x80 edge) then enable
        assert b.rig.drive(4).state == "OPERATION ENABLED"
        assert node.sdo[0x1001].raw == 0
    finally:
        b.close()


def test_encoder_edges_set_where_an_axis_counts():
    """An axis reads ``rint(position * counts_per_unit + edge)`` counts, less that reading at
    power-up; a fraction of a count of edge changes the reading of some positions by one."""
    edges = np.array([0.0, 0.3, -0.4, 0.25, 0.0, -0.1])
    b = Bench(encoder_edges=edges)
    try:
        rig = b.rig
        counts_per_unit = np.array([(REV if j < 3 else PRI).counts_per_unit for j in range(6)])
        x0 = rig.plant.Theta * counts_per_unit
        # per axis a move of 10 to 11 counts whose reading depends on the edge (where one can)
        move = np.full(6, 10.5)
        for j in range(6):
            for d in np.linspace(0.0, 0.95, 20):
                with_edge = np.rint(x0[j] + edges[j] + 10 + d) - np.rint(x0[j] + edges[j])
                if with_edge != np.rint(x0[j] + 10 + d) - np.rint(x0[j]):
                    move[j] = 10 + d
                    break
        expected = np.rint(x0 + edges + move) - np.rint(x0 + edges)
        differs = expected != np.rint(x0 + move) - np.rint(x0)
        assert differs[edges != 0].all()
        rig.start()
        with rig._lock:          # the axes unpowered, at rest: the plant stays where it is put
            rig.plant.Theta = rig.plant.Theta + move / counts_per_unit
        time.sleep(0.3)          # the rig's clock moves an idle plant (and samples it) every few ms
        read = [node.sdo[0x6064].raw for node in b.nodes]
        assert read == expected.astype(int).tolist()
    finally:
        b.close()
