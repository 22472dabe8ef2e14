"""drivers.bus: periodic frames on a thread-timed bus (python-can's virtual bus) keep to the grid.

python-can's thread-based periodic task sends the slots it missed back to back once its thread
runs again; for SYNC that gives the drives several cycles before the master could answer the
first. The network's own task skips them. The stall here is real: the test holds the network's
send lock, so the producer thread blocks in its send as it would behind a busy GIL.
"""

import itertools
import queue
import time

import can
import numpy as np
import pytest

from drivers.bus import BusConfig, GridPeriodicTask, open_bus, open_network
from drivers.cia import SYNC_COB_ID

PERIOD = 0.005
_channels = itertools.count()


@pytest.fixture
def network_and_listener():
    channel = f"bus-test-{next(_channels)}"
    network = open_network(BusConfig("virtual", channel, ignore_config=True))
    listener = can.Bus(interface="virtual", channel=channel, ignore_config=True)
    yield network, listener
    listener.shutdown()
    network.disconnect()


def _receive(bus, seconds):
    stamps, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        msg = bus.recv(0.05)
        if msg is not None and msg.arbitration_id == SYNC_COB_ID:
            stamps.append(msg.timestamp)
    return np.array(stamps)


def test_a_stalled_producer_skips_the_missed_slots_instead_of_bursting(network_and_listener):
    network, listener = network_and_listener
    assert not network.timer_periodic              # the virtual bus has no timer of its own
    task = network.send_periodic(SYNC_COB_ID, b"", PERIOD)
    assert isinstance(task, GridPeriodicTask)
    try:
        time.sleep(0.1)
        with network.send_lock:                    # the producer blocks in its next send
            time.sleep(12 * PERIOD)
        stamps = _receive(listener, 0.3)
    finally:
        task.stop()
    gaps = np.diff(stamps)
    # the slots of the stall are skipped and counted; what is sent keeps half a period apart
    assert task.skipped >= 10
    assert gaps.min() > 0.4 * PERIOD, gaps.min()
    # and after the stall it is back on the period
    assert abs(np.median(gaps) - PERIOD) < 0.2 * PERIOD
    count = task.sent
    time.sleep(3 * PERIOD)
    assert task.sent == count                      # stop() ends the thread


def test_python_cans_thread_task_would_burst_after_the_same_stall(network_and_listener):
    """The contrast, on the same bus: python-can's own task, stalled the same way (its send lock),
    sends the missed slots back to back."""
    network, listener = network_and_listener
    task = network.bus.send_periodic(can.Message(arbitration_id=SYNC_COB_ID, is_extended_id=False), PERIOD)
    try:
        time.sleep(0.1)
        with task.send_lock:
            time.sleep(12 * PERIOD)
        stamps = _receive(listener, 0.3)
    finally:
        task.stop()
    assert np.count_nonzero(np.diff(stamps) < 0.4 * PERIOD) >= 5


@pytest.mark.parametrize("ours", [True, False])
def test_the_virtual_bus_queues_its_own_echo_before_another_bus_gets_the_frame(ours):
    """A receiver opened earlier (the in-process rig) must not be able to answer a SYNC before
    the master's own SYNC echo is queued: the answer would fall into the cycle before. python-can's
    bus delivers in the order the buses were opened; ours puts the echo first."""
    channel = f"bus-test-{next(_channels)}"
    earlier = can.Bus(interface="virtual", channel=channel, ignore_config=True)
    config = BusConfig("virtual", channel, ignore_config=True)
    sender = open_bus(config) if ours else can.Bus(interface="virtual", channel=channel,
                                                   receive_own_messages=True, ignore_config=True)
    echo_queued = []

    class Spy(queue.Queue):    # the earlier bus's queue, noting whether the echo was already there
        def put(self, item, block=True, timeout=None):
            echo_queued.append(not sender.queue.empty())
            super().put(item, block, timeout)

    spy = Spy()
    earlier.channel[earlier.channel.index(earlier.queue)] = spy
    earlier.queue = spy
    try:
        for counter in (1, 2, 3):
            sender.send(can.Message(arbitration_id=SYNC_COB_ID, data=[counter], is_extended_id=False))
            assert sender.recv(1.0).data[0] == counter and earlier.recv(1.0).data[0] == counter
    finally:
        earlier.shutdown()
        sender.shutdown()
    assert echo_queued == [ours] * 3


def test_a_udp_multicast_bus_hears_its_own_group_only():
    """Linux hands a socket the datagrams of every group joined on its port unless told not to:
    two rigs (or two test runs) on two groups of one host must not hear each other."""
    pytest.importorskip("msgpack", reason="python-can's udp_multicast interface needs msgpack")
    from udp_groups import interface_local_group, loopback_multicast_works
    mine, other = interface_local_group(), interface_local_group()
    if not loopback_multicast_works(mine):
        pytest.skip("this host does not loop IPv6 multicast back to its own sockets")
    buses = [open_bus(BusConfig("udp_multicast", g)) for g in (mine, mine, other)]
    try:
        sender, same, elsewhere = buses
        sender.send(can.Message(arbitration_id=0x123, data=b"\x01", is_extended_id=False))
        assert same.recv(1.0).arbitration_id == 0x123
        assert elsewhere.recv(0.3) is None
    finally:
        for bus in buses:
            bus.shutdown()
