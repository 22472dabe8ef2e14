"""The drive profiles and their object dictionaries agree with each other and with the devices."""

import dataclasses

import pytest
from canopen.objectdictionary import ODVariable

from drivers.profiles import PROFILES, ObjectRef, get_profile, make_object_dictionary


def _refs(profile):
    for field in dataclasses.fields(profile):
        value = getattr(profile, field.name)
        if isinstance(value, ObjectRef):
            yield field.name, value
        elif isinstance(value, tuple):
            for i, item in enumerate(value):
                if isinstance(item, ObjectRef):      # not the firmware gaps: objects a firmware lacks
                    yield f"{field.name}[{i}]", item


@pytest.mark.parametrize("name", sorted(PROFILES))
def test_every_named_object_is_in_the_od_with_its_type(name):
    prof = PROFILES[name]
    od = make_object_dictionary(name, 5)
    seen = 0
    for field, ref in _refs(prof):
        var = od.get_variable(ref.index, ref.subindex)
        assert isinstance(var, ODVariable), f"{prof.name}.{field} {ref} missing from the OD"
        assert var.data_type == ref.type_code, f"{prof.name}.{field} {ref} has the wrong type"
        seen += 1
    assert seen >= 25


def test_generation_specific_objects():
    od2, od4 = make_object_dictionary("epos2", 1), make_object_dictionary("EPOS4", 1)
    assert 0x6078 in od2 and 0x6078 not in od4
    assert 0x30D1 in od4 and 0x30D1 not in od2
    assert 0x60C2 in od4 and 0x60C2 not in od2
    assert PROFILES["epos2"].torque_constant is None and 0x3001 not in od2
    assert od4[0x30D1][2].pdo_mappable and od2[0x6078].pdo_mappable
    assert od2[0x1008].default == "EPOS2 70/10" and od4[0x1008].default == "EPOS4 50/5"


def test_supported_modes_bits_match_profile():
    od4 = make_object_dictionary("epos4", 3)
    bits = od4[0x6502].default
    # CiA 402: bit 0 PPM, 2 PVM, 5 HMM, 7 CSP, 8 CSV, 9 CST
    assert bits == (1 << 0) | (1 << 2) | (1 << 5) | (1 << 7) | (1 << 8) | (1 << 9)
    assert PROFILES["epos4"].cyclic_mode in PROFILES["epos4"].supported_modes
    assert PROFILES["epos2"].cyclic_mode in PROFILES["epos2"].supported_modes


def test_tpdo1_of_epos2_fits_one_frame():
    p = PROFILES["epos2"]
    assert p.position_actual.bits + p.current_actual.bits + p.statusword.bits == 8 * p.max_tpdo_bytes
    p4 = PROFILES["epos4"]
    assert p4.position_actual.bits + p4.current_actual.bits == 8 * p4.max_tpdo_bytes


def test_communication_defaults_are_node_relative():
    od = make_object_dictionary("epos2", 12)
    assert od[0x1014].default == 0x80 + 12
    assert od[0x1018][1].default == 0xFB
    assert od[0x1800][1].default == 0x180 + 12
    assert od[0x1401][1].default == (1 << 31) | (0x300 + 12)


@pytest.mark.parametrize("bad", ["epos3", "", None])
def test_unknown_profile_is_a_clear_error(bad):
    with pytest.raises(ValueError, match="unknown drive profile"):
        get_profile(bad)


@pytest.mark.parametrize("node_id", [0, 128, "3"])
def test_node_id_out_of_range(node_id):
    with pytest.raises(ValueError, match="node-ID"):
        make_object_dictionary("epos4", node_id)


def test_bad_data_type_name():
    with pytest.raises(ValueError, match="unknown CANopen data type"):
        ObjectRef(0x6064, 0, "INT32")
