"""Master-side pieces that need no drive: bus-load budget, EMCY texts, the SYNC-cycle assembler
fed with hand-made frames, recordings on disk and the raw-log decoder."""

import dataclasses
import json

import can
import canopen
import numpy as np
import pytest

from drivers.acquisition import (LOOKAHEAD, AxisLayout, CycleAssembler, CycleBooks, PdoFrame, master_layouts,
                                 pdo_layout)
from drivers.axis import AxisConfig
from drivers.bus import BusConfig, check_bus_load, frame_bits, max_sync_rate, notifier_of, open_network
from drivers.emcy import describe
from drivers.epos import DriveGroup
from drivers.errors import BusLoadError, ConfigError, RecordingError
from drivers.recording import (FlushingLogger, Recording, SampleRecorder, decode_log, rows_to_arrays,
                               sidecar_path)
from drivers.recording_metadata import RecordingMetadata
from drivers.supervision import Watchdogs
from drivers.sync import SyncReport
from drivers.units import AxesScaling, AxisScaling


def test_frame_bits_match_worst_case_stuffing_formula():
    # 8 data bytes: 47 + 64 + floor((34 + 64 - 1) / 4) = 135 bits; SYNC (no data): 55 bits
    assert frame_bits(8) == 135 and frame_bits(0) == 55
    assert [frame_bits(n) for n in range(9)] == [47 + 8 * n + (33 + 8 * n) // 4 for n in range(9)]


def test_bus_load_refuses_six_drives_at_1khz_on_1mbit():
    sizes = [0] + [8, 6] * 6  # SYNC + TPDO1 + RPDO1 per drive
    with pytest.raises(BusLoadError, match=r"156%.*643 Hz"):
        check_bus_load(sizes, 1e-3, 1_000_000)
    assert check_bus_load(sizes, 4e-3, 1_000_000) == pytest.approx(1555 * 250 / 1e6)
    assert check_bus_load(sizes, 1e-3, None) == 0.0
    assert max_sync_rate(sizes, 1_000_000) == pytest.approx(1e6 / 1555)  # 643 Hz
    assert max_sync_rate(sizes, 1_000_000, background_bits_per_s=2e6) == 0.0


def test_bus_config_from_mapping_names_bad_key():
    cfg = BusConfig.from_mapping({"interface": "virtual", "channel": "x", "fd": False})
    assert cfg.options == {"fd": False}
    with pytest.raises(ConfigError, match="bus: missing key 'channel'"):
        BusConfig.from_mapping({"interface": "virtual"})
    with pytest.raises(ConfigError, match="bus.bitrate"):
        BusConfig.from_mapping({"interface": "virtual", "channel": "x", "bitrate": -1})


def test_emcy_texts_per_generation():
    assert describe(0x8611) == "Following error"
    assert describe(0x2310, "EPOS4") == "Overcurrent error"
    assert describe(0xFF01, "EPOS2") == "Hall sensor error"
    assert describe(0xFF01, "epos4") == "System overloaded error"
    assert describe(0x2399) == "unknown Current code"


def _axes(profile="epos4", n=2):
    scaling = AxisScaling("revolute", 2048, 0.0369, gear_ratio=26.0)
    return [AxisConfig(f"a{i}", i + 1, profile, scaling, -6.0, 6.0, 3.0, 4.0, 0.05) for i in range(n)]


def _frames(axes, k, counts, ma, sw=0x0237, drop=()):
    """Frames of cycle k as the drives and the master send them (SYNC, TPDOs, RPDO echo)."""
    msgs = [can.Message(arbitration_id=0x80, data=b"", is_extended_id=False, timestamp=k * 0.004)]
    for i, a in enumerate(axes):
        for f in pdo_layout(a.drive_profile):
            if (i, f.direction, f.number) in drop:
                continue
            values = {"position": counts[i], "current": ma[i], "statusword": sw, "velocity": 7,
                      "target": counts[i] + 1, "controlword": 0x0F}
            data = f.struct.pack(*[values[name] for name, _ in f.entries])
            msgs.append(can.Message(arbitration_id=f.cob_id(a.node_id), data=data, is_extended_id=False,
                                    timestamp=k * 0.004 + 1e-4 * (i + 1)))
    return msgs


@pytest.mark.parametrize("profile", ["epos2", "epos4"])
def test_assembler_flags_missing_and_late_frames_never_fills(profile):
    axes = _axes(profile)
    layouts = master_layouts(axes)
    rows = []
    asm = CycleAssembler(layouts, rows.append)
    msgs = []
    n = LOOKAHEAD + 4     # the frame lost in cycle 2 is taken as lost after LOOKAHEAD cycles
    for k in range(n):
        drop = {(1, "tpdo", 1)} if k == 2 else set()
        msgs += _frames(axes, k, [100 * k, -100 * k], [10 * k, -10 * k], drop=drop)
    # the TPDO1 of axis 0 of cycle 3 comes late, after the SYNC of cycle 4
    late = next(m for m in msgs if m.arbitration_id == 0x181 and m.timestamp == pytest.approx(3 * 0.004 + 1e-4))
    msgs.remove(late)
    msgs.insert(msgs.index(_sync_at(msgs, 4)) + 1, late)
    for m in msgs + [_frames(axes, n, [0, 0], [0, 0])[0]]:
        asm.on_message_received(m)
    assert [r.cycle for r in rows] == list(range(n))
    assert rows[1].position == [100, -100] and rows[1].current == [10, -10] and rows[1].valid == [True, True]
    assert rows[2].valid == [True, False] and rows[2].position == [200, None]
    # cycle 4 got two frames: the first paid cycle 3's, the last is its own
    assert rows[3].valid == [False, True] and rows[3].position[0] is None
    assert rows[4].valid == [True, True] and rows[4].position == [400, -400]
    assert asm.late_frames == 1 and asm.invalid_cycles == 2
    # the RPDO echoes seen in cycle k are the set-points of cycle k+1
    assert rows[0].target == [None, None] and rows[3].target == [201, -199]


def test_assembler_places_no_frame_in_another_cycle():
    """Hand-made traffic of two axes; axis 0's TPDO1 is late by one cycle for a run of cycles,
    lost once, sent twice once, late by two in a burst, and lost just before the end. Each frame
    carries its cycle in the position; no valid cell may hold another cycle's."""
    axes = _axes("epos2")
    layouts = master_layouts(axes)
    n = 75
    arrivals = {k: [k] for k in range(n)}           # cycle -> windows its axis-0 TPDO1 arrives in
    for k in (3, 4, 5):
        arrivals[k] = [k + 1]
    arrivals[10] = []
    arrivals[40] = [40, 40]
    arrivals[50], arrivals[51] = [52], [52]
    arrivals[70] = []
    window_frames = {w: [] for w in range(n + 1)}
    for k in range(n):
        for m in _frames(axes, k, [1000 * k, -1000 * k], [k, -k]):
            if m.arbitration_id == 0x181:
                for w in arrivals[k]:
                    window_frames[w].append(m)
            elif m.arbitration_id != 0x80:
                window_frames[k].append(m)
    rows = []
    asm = CycleAssembler(layouts, rows.append, max_cycles=n)
    for w in range(n + 1):
        asm.on_message_received(can.Message(arbitration_id=0x80, data=b"", is_extended_id=False))
        for m in window_frames[w]:
            asm.on_message_received(m)
    assert [r.cycle for r in rows] == list(range(n))
    for r in rows:
        for i in range(2):
            if r.valid[i]:
                assert r.position[i] == (1000 if i == 0 else -1000) * r.cycle, (r.cycle, i)
    invalid = [r.cycle for r in rows if not r.valid[0]]
    # 3-5 shifted (cycle 6 holds its own after the extra frame), 10 lost, 40 sent twice,
    # 50-51 late (52 its own), 70 lost and 71-74 undecided at the end
    assert invalid == [3, 4, 5, 10, 40, 50, 51, 70, 71, 72, 73, 74]
    assert all(r.valid[1] for r in rows)
    assert (asm.late_frames, asm.lost_frames, asm.unplaced_frames) == (3, 1, 1)
    assert asm.withdrawn_cells == 2 + 1 + 4       # 4, 5; 40; 71..74


def _sync_at(msgs, k):
    return next(m for m in msgs if m.arbitration_id == 0x80 and m.timestamp == pytest.approx(k * 0.004))


def test_assembler_reports_statusword_fault_once():
    axes = _axes("epos2")
    seen = []
    asm = CycleAssembler(master_layouts(axes),
                         lambda r: None, on_status=lambda i, sw: seen.append((i, sw)))
    for k in range(3):
        for m in _frames(axes, k, [0, 0], [0, 0], sw=0x0237 if k == 0 else 0x2237):
            asm.on_message_received(m)
    assert seen == [(0, 0x2237), (1, 0x2237)]


@pytest.mark.parametrize("suffix", [".log", ".asc", ".blf"])
def test_decode_log_reproduces_rows_from_hand_made_traffic(tmp_path, suffix):
    axes = _axes("epos4", 3)
    layouts = master_layouts(axes)
    rows = []
    logger = FlushingLogger(tmp_path / f"raw{suffix}")
    asm = CycleAssembler(layouts, rows.append, forward=[logger], max_cycles=40)
    rng = np.random.default_rng(0)
    for k in range(45):
        counts = rng.integers(-2**31, 2**31, 3)
        ma = rng.integers(-2**31, 2**31, 3)
        for m in _frames(axes, k, counts.tolist(), ma.tolist()):
            m.timestamp += 1.7e9
            asm.on_message_received(m)
    logger.stop()
    live = Recording.from_chunks([rows_to_arrays(rows, axes)], 3, RecordingMetadata())
    replay = decode_log(tmp_path / f"raw{suffix}", axes, max_cycles=40, layouts=layouts, layout_source="by hand")
    assert live.metadata.n_cycles == replay.metadata.n_cycles == 40
    assert replay.metadata.pdo_layout_source == "given: by hand"
    for name in ("cycle", "position", "velocity", "current", "statusword", "target", "valid"):
        np.testing.assert_array_equal(getattr(live, name), getattr(replay, name), err_msg=name)
    np.testing.assert_allclose(live.t, replay.t, rtol=0, atol=1.01e-6)


def test_recording_round_trip_and_bad_files(tmp_path):
    axes = _axes()
    rows = []
    asm = CycleAssembler(master_layouts(axes), rows.append)
    for k in range(4):
        for m in _frames(axes, k, [4096 * k, 0], [1500, -20]):
            asm.on_message_received(m)
    rec = Recording.from_chunks([rows_to_arrays(rows, axes)], 2, RecordingMetadata(extra={"note": "x"}))
    # 4096 counts = 2 motor turns = 2/26 joint turns
    np.testing.assert_allclose(rec.position[1], [2 * 2 * np.pi / 26, 0.0])
    np.testing.assert_array_equal(rec.current[1], [1.5, -0.02])
    back = Recording.load(rec.save(tmp_path / "r.npz"))
    np.testing.assert_array_equal(back.position, rec.position)
    assert back.metadata.extra["note"] == "x" and back.metadata.n_cycles == 3
    np.save(tmp_path / "other.npy", np.zeros(3))
    with pytest.raises(RecordingError, match="other.npy"):
        Recording.load(tmp_path / "other.npy")
    with pytest.raises(ConfigError, match="suffix"):
        FlushingLogger(tmp_path / "raw.txt")


def test_drive_group_takes_bus_settings_from_the_network_and_checks_master_id():
    axes = _axes("epos4", 3)
    with pytest.raises(ConfigError, match="open_network"):
        DriveGroup(canopen.Network(), axes)
    network = open_network(BusConfig("virtual", "offline-group", bitrate=500_000, ignore_config=True))
    try:
        group = DriveGroup(network, axes)
        assert group.bitrate == 500_000 and network.config.bitrate == 500_000
        with pytest.raises(ConfigError, match=r"master_id .* \(drives: \[1, 2, 3\]\)"):
            DriveGroup(network, axes, master_id=2)
        with pytest.raises(ConfigError, match="drive_heartbeat timeout: need heartbeat period < timeout"):
            DriveGroup(network, axes, Watchdogs(heartbeat_period=0.1, drive_heartbeat=0.05))
        with pytest.raises(ConfigError, match="master_heartbeat timeout: .* 65.535 s"):
            Watchdogs(master_heartbeat=70.0)
        # written out: per cycle a SYNC (0 bytes, 55 bits) and per EPOS4 drive TPDO1 (position +
        # current, 8 bytes: 135 bits), TPDO2 (velocity + statusword, 6 bytes: 115 bits) and RPDO1
        # (set-point + controlword, 6 bytes: 115 bits), at 250 Hz; plus four heartbeats (three
        # drives and the master's own, 1 byte: 65 bits) per 0.1 s
        bits_per_s = (55 + 3 * (135 + 115 + 115)) * 250 + 4 * 65 / 0.1
        assert group.check_bus_load(0.004) == pytest.approx(bits_per_s / 500_000, rel=1e-12)
    finally:
        network.disconnect()


def test_axes_scaling_converts_columns_by_hand_values():
    """A revolute axis (2048 counts/turn, gear 26, K_m 0.0369 N·m/A) and a carriage (2048
    counts/turn, 2 mm lead, K_m 0.0603): values computed by hand from the drive data."""
    rev = AxisScaling("revolute", 2048, 0.0369, gear_ratio=26.0)
    lin = AxisScaling("prismatic", 2048, 0.0603, screw_lead=0.002)
    units = AxesScaling([rev, lin])
    counts = units.counts_from_position([[1.0, 0.01]])
    assert counts.tolist() == [[round(2048 * 26 / (2 * np.pi)), round(2048 * 0.01 / 0.002)]]  # 8475, 10240
    np.testing.assert_allclose(units.position_from_counts([[8475, 10240]]),
                               [[8475 * 2 * np.pi / (2048 * 26), 0.01]], rtol=1e-15)
    assert units.rpm_from_velocity([[1.0, 0.002]]).tolist() == [[round(60 * 26 / (2 * np.pi)), 60]]
    assert units.ma_from_current([[0.5, -1.2346]]).tolist() == [[500, -1235]]
    np.testing.assert_allclose(units.force_from_current([[1.0, 1.0]]),
                               [[0.0369 * 26, 0.0603 * 2 * np.pi / 0.002]], rtol=1e-15)
    np.testing.assert_allclose(units.current_from_force(units.force_from_current([[0.3, -0.7]])), [[0.3, -0.7]])


def _layout_frames(axes, layouts, k, values, sync_stamp=None):
    """Frames of cycle k for ``layouts`` (SYNC, then each axis's TPDOs and RPDO echo), the fields'
    values (drive units) per axis from ``values(k, i)``."""
    stamp = k * 0.004 if sync_stamp is None else sync_stamp
    msgs = [can.Message(arbitration_id=0x80, data=b"", is_extended_id=False, timestamp=stamp)]
    for i, layout in enumerate(layouts):
        for f in layout.frames:
            v = values(k, i)
            data = f.struct.pack(*[v[name] for name, _ in f.entries])
            msgs.append(can.Message(arbitration_id=f.cob_id(layout.node_id), data=data, is_extended_id=False,
                                    timestamp=stamp + 1e-4 * (i + 1)))
    return msgs


def test_a_lost_velocity_frame_leaves_position_and_current_valid():
    """EPOS4 axes: TPDO1 (position, current) and TPDO2 (velocity, statusword). A lost TPDO2
    leaves its axis's position and current in the row (validity per TPDO); a lost TPDO1 leaves
    its velocity. Every frame carries its cycle in its values."""
    axes = _axes("epos4", 2)
    layouts = master_layouts(axes)
    rows = []
    asm = CycleAssembler(layouts, rows.append, max_cycles=30)
    lose = {(5, 0x281), (9, 0x182)}           # cycle 5: axis 0's TPDO2; cycle 9: axis 1's TPDO1
    for k in range(31):
        for m in _layout_frames(axes, layouts, k, lambda k, i: {
                "position": 100 * k + i, "current": 10 * k + i, "velocity": 1000 + k, "statusword": 0x0237,
                "target": 0, "controlword": 0x0F}):
            if (k, m.arbitration_id) not in lose:
                asm.on_message_received(m)
    assert len(rows) == 30
    assert rows[5].valid == [False, True] and rows[5].velocity == [None, 1005]
    assert rows[5].position == [500, 501] and rows[5].current == [50, 51]
    assert rows[9].valid == [True, False] and rows[9].position == [900, None] and rows[9].current == [90, None]
    assert rows[9].velocity == [1009, 1009]
    rec = Recording.from_chunks([rows_to_arrays(rows, axes)], 2, RecordingMetadata())
    np.testing.assert_array_equal(rec.velocity_valid[5], [False, True])
    np.testing.assert_array_equal(rec.position_valid[5], [True, True])
    np.testing.assert_array_equal(rec.current_valid[9], [True, False])
    assert rec.n_invalid == 2 and np.isnan(rec.velocity[5, 0]) and np.isfinite(rec.position[5]).all()


def _changed_layout(axis):
    """An EPOS4 layout other than today's: TPDO1 current (the averaged one, 0x30D1:01) before
    position, TPDO2 statusword before velocity; the RPDO as today."""
    profile = axis.drive_profile
    return AxisLayout(axis.node_id, (
        PdoFrame("tpdo", 1, (("current", profile.current_averaged), ("position", profile.position_actual)), 1),
        PdoFrame("tpdo", 2, (("statusword", profile.statusword), ("velocity", profile.velocity_actual)), 1),
        next(f for f in pdo_layout(profile) if f.direction == "rpdo")))


@pytest.mark.parametrize("suffix", [".log", ".asc", ".blf"])
def test_raw_logs_of_today_s_layout_and_of_a_changed_one_both_decode(tmp_path, suffix, caplog):
    """Two runs' raw logs, one with today's PDO layout, one with another (objects in another
    order, another current object), each written with its sidecar: both decode to the values the
    drives sent (counts, mA, rpm converted by hand). Without its sidecar the changed log would be
    read with today's layout, to wrong values marked valid: it is refused, unless a layout is given
    (then the metadata says which)."""
    axes = _axes("epos4", 2)
    scaling = axes[0].scaling
    values = lambda k, i: {"position": 4096 * k + 7 * i, "current": 300 + 10 * k - 600 * i,  # noqa: E731
                           "velocity": 60 * k + i, "statusword": 0x0237, "target": 4096 * (k + 1), "controlword": 0x0F}
    n = 12
    for label, layouts in (("today", master_layouts(axes)),
                           ("changed", [_changed_layout(a) for a in axes])):
        path = tmp_path / f"{label}{suffix}"
        logger = FlushingLogger(path, layouts=layouts)
        for k in range(n + 1):
            for m in _layout_frames(axes, layouts, k, values, sync_stamp=1.7e9 + k * 0.004):
                logger.on_message_received(m)
        logger.stop()
        rec = decode_log(path, axes, max_cycles=n)
        assert rec.metadata.pdo_layout_source.startswith("stored") and rec.n_invalid == 0, label
        assert rec.metadata.pdo_layout == tuple(layouts)
        k = np.arange(n)[:, None]
        i = np.arange(2)[None, :]
        # by hand: 4096 counts = 2 motor turns = 2/26 joint turns; mA / 1000; rpm of the motor / gear
        np.testing.assert_allclose(rec.position, (4096 * k + 7 * i) * 2 * np.pi / (2048 * 26), rtol=1e-12, err_msg=label)
        np.testing.assert_allclose(rec.current, (300 + 10 * k - 600 * i) / 1000, rtol=1e-12, err_msg=label)
        np.testing.assert_allclose(rec.velocity, (60 * k + i) * 2 * np.pi / 60 / 26, rtol=1e-12, err_msg=label)
        assert scaling.counts_per_turn == 2048 and scaling.gear_ratio == 26.0
    sidecar_path(tmp_path / f"changed{suffix}").unlink()
    with pytest.raises(RecordingError, match=rf"changed{suffix}: no changed{suffix}\.json beside it with the PDO "
                                             r"layout it was recorded with; .*wrong values marked valid"):
        decode_log(tmp_path / f"changed{suffix}", axes, max_cycles=n)
    wrong = decode_log(tmp_path / f"changed{suffix}", axes, max_cycles=n, layouts=master_layouts(axes),
                       layout_source="today's")
    assert wrong.metadata.pdo_layout_source == "given: today's"
    assert not np.allclose(wrong.position, rec.position)


def test_a_raw_log_names_the_nodes_its_layout_was_recorded_from(tmp_path):
    axes = _axes("epos4", 2)
    path = tmp_path / "other.log"
    FlushingLogger(path, layouts=[AxisLayout(a.node_id + 10, pdo_layout(a.drive_profile)) for a in axes]).stop()
    with pytest.raises(RecordingError, match=r"recorded from nodes \[11, 12\].*nodes \[1, 2\]"):
        decode_log(path, axes)
    sidecar_path(path).write_text("{not json")
    with pytest.raises(RecordingError, match="damaged sidecar"):
        decode_log(path, axes)


def test_the_set_points_are_the_ones_sent_not_the_echo_order(tmp_path):
    """The master sends the set-point of cycle k+1 after SYNC k; cycle 6's echo comes back after
    SYNC 6 (late, or out of order on a loaded SocketCAN). Read from the echoes, row 6 would hold
    cycle 5's set-point; the recording and the decoded raw log both hold the sent ones and count
    the row in ``late_setpoints``."""
    axes = _axes("epos4", 2)
    layouts = master_layouts(axes)
    n = 10
    sent = np.array([[1000 * k, -1000 * k] for k in range(n)], dtype=np.int64)
    log = tmp_path / "run.log"
    raw = FlushingLogger(log, layouts=layouts, setpoints=sent)
    recorder = SampleRecorder(axes, tmp_path / "run.npz", RecordingMetadata(n_targets=n), layouts=layouts, setpoints=sent)
    asm = CycleAssembler(layouts, recorder.put, max_cycles=n, forward=[raw])
    recorder.start()
    echoes = [can.Message(arbitration_id=0x200 + a.node_id, is_extended_id=False,
                          data=layouts[0].frames[-1].struct.pack(int(sent[0, i]), 0x0F)) for i, a in enumerate(axes)]
    for m in echoes:
        asm.on_message_received(m)
    held = []
    for k in range(n + 1):
        msgs = _layout_frames(axes, layouts, k, lambda k, i: {
            "position": k, "current": k, "velocity": k, "statusword": 0x0237,
            "target": int(sent[min(k + 1, n - 1), i]), "controlword": 0x0F})
        sync, rest = msgs[0], msgs[1:]
        asm.on_message_received(sync)
        for m in held:
            asm.on_message_received(m)
        held = [m for m in rest if m.arbitration_id >= 0x200] if k == 5 else []
        for m in rest:
            if m not in held:
                asm.on_message_received(m)
    raw.stop()
    rec = recorder.close()
    units = AxesScaling([a.scaling for a in axes])
    np.testing.assert_array_equal(rec.target, units.position_from_counts(sent))
    assert rec.metadata.late_setpoints == 1 and rec.metadata.setpoints == "sent"
    echoed = units.position_from_counts(sent)
    echoed[6] = echoed[5]
    np.testing.assert_array_equal(rows_to_arrays_target(log, axes, n), echoed)     # what the echoes said
    again = Recording.load(tmp_path / "run.npz")
    np.testing.assert_array_equal(again.target, rec.target)
    assert again.metadata.late_setpoints == 1 and again.metadata.pdo_layout == tuple(layouts)
    replay = decode_log(log, axes, max_cycles=n)
    np.testing.assert_array_equal(replay.target, rec.target)
    assert replay.metadata.late_setpoints == 1


def rows_to_arrays_target(log, axes, n):
    """The set-points a raw log's RPDO echoes give, read without its sidecar's sent ones."""
    layouts = master_layouts(axes)
    rows = []
    asm = CycleAssembler(layouts, rows.append, max_cycles=n)
    with can.LogReader(log) as reader:
        for m in reader:
            asm.on_message_received(m)
    return rows_to_arrays(rows, axes)["target"]


def test_recording_metadata_round_trips_through_its_json_form():
    """Every field of the metadata comes back from the JSON stored in the NPZ, the nested
    records and the free-form ``extra`` at its top level."""
    axes = [AxisConfig("theta1", 1, "epos2", AxisScaling("revolute", 2048, 0.0369, gear_ratio=26.0),
                       -1.0, 1.0, 1.0, 10.0, 1.0, current="averaged"),
            AxisConfig("zeta1", 4, "epos4", AxisScaling("prismatic", 2048, 0.0603, screw_lead=0.002),
                       -0.1, 0.1, 0.05, 4.0, 0.002)]
    meta = dataclasses.replace(
        RecordingMetadata(trajectory="square", config="sim.yaml", current="averaged", status="complete",
                          format_version=2, pdo_layout=master_layouts(axes), sync="periodic", sync_period=0.004,
                          bus_load=0.3, bitrate=1_000_000, n_targets=10, t0=12.5, n_cycles=10, invalid_cycles=1,
                          setpoints="sent", late_setpoints=2, buffer_overflows=0,
                          books=CycleBooks(late_frames=3, unplaced_frames=1),
                          sync_report=SyncReport(sync_slots_skipped=4, sync_warning="late"), raw_log="square.log",
                          gc_collections=2, gc_longest_pause=1e-3, log_truncated=True, nodes_heard=(1, 4),
                          extra={"operator": "me", "run": [1, 2]}),
        ).with_axes(axes)
    doc = json.loads(meta.to_json())
    assert doc["late_frames"] == 3 and doc["sync_slots_skipped"] == 4 and doc["operator"] == "me"
    assert doc["axes"][0]["units"]["position"] == "rad" and doc["axes"][1]["scaling"]["screw_lead"] == 0.002
    assert RecordingMetadata.from_json(meta.to_json()) == meta
    with pytest.raises(ValueError, match="n_cycles"):
        RecordingMetadata(extra={"n_cycles": 3})


def test_metadata_as_recordings_stored_it_before_loads_typed():
    """The flat JSON of a recording written before the metadata was typed: the known keys fill
    their fields (missing ones keep their defaults), the retired ``with_velocity`` is dropped,
    an unknown key is kept in ``extra``."""
    stored = {"trajectory": "square", "config": "sim.yaml", "current": "instantaneous", "sync_period": 0.004,
              "with_velocity": True, "bus_load": 0.2, "bitrate": 1000000, "n_targets": 5, "sync": "lockstep",
              "axes": [{"name": "theta1", "node_id": 1, "profile": "EPOS2", "units": {"position": "rad"},
                        "scaling": {"kind": "revolute", "counts_per_turn": 2048, "torque_constant": 0.0369,
                                    "gear_ratio": 26.0, "screw_lead": None}, "current": "instantaneous"}],
              "format_version": 2, "status": "complete", "buffer_overflows": 0, "t0": 1.5, "n_cycles": 5,
              "invalid_cycles": 0, "late_frames": 1, "lost_frames": 0, "withdrawn_cells": 0, "unplaced_frames": 0,
              "error_frames": 0, "raw_log": None, "gc_collections": 0, "gc_longest_pause": 0.0,
              "lockstep_retries": 2, "lockstep_waited_out": 0, "late_setpoints": 0, "setpoints": "sent",
              "site": "lab 2"}
    meta = RecordingMetadata.from_json(json.dumps(stored))
    assert (meta.trajectory, meta.sync_period, meta.sync, meta.n_cycles, meta.t0) == ("square", 0.004, "lockstep", 5, 1.5)
    assert meta.books == CycleBooks(late_frames=1) and meta.sync_report == SyncReport(lockstep_retries=2,
                                                                                      lockstep_waited_out=0)
    assert meta.axes[0].profile == "EPOS2" and meta.axes[0].scaling.gear_ratio == 26.0
    assert dict(meta.extra) == {"site": "lab 2"} and meta.pdo_layout == () and meta.file is None


def test_a_raw_log_closed_while_the_notifier_delivers_a_frame_leaves_it_out(tmp_path):
    """python-can's notifier may still be delivering a frame when a stream closes (removing a
    listener does not wait for it; a master behind the bus after a hold-up often is): the closed
    raw log leaves the frame out instead of raising in the notifier thread, which would end it."""
    path = tmp_path / "raw.log"
    logger = FlushingLogger(path)
    frame = can.Message(arbitration_id=0x181, data=b"\x01\x02", is_extended_id=False, timestamp=1.7e9)
    logger.on_message_received(frame)
    logger.stop()
    logger.on_message_received(frame)
    assert len(path.read_text().splitlines()) == 1


def test_watchdog_timeouts_are_filled_in_and_a_network_without_notifier_is_refused():
    """The heartbeat timeouts a DriveGroup uses: the given ones, else 3.5 heartbeat periods; the
    notifier listeners are added to: a connected network's, a clear error for one not connected."""
    filled = Watchdogs(heartbeat_period=0.2)
    assert (filled.drive_timeout, filled.master_timeout) == (3.5 * 0.2, 3.5 * 0.2)
    given = Watchdogs(heartbeat_period=0.1, drive_heartbeat=0.5, master_heartbeat=0.45)
    assert (given.drive_timeout, given.master_timeout) == (0.5, 0.45)
    with pytest.raises(ConfigError, match="not connected .*open_network"):
        notifier_of(canopen.Network())
    network = open_network(BusConfig("virtual", "offline-notifier", ignore_config=True))
    try:
        assert notifier_of(network) is network.notifier and network.notifier is not None
    finally:
        network.disconnect()
