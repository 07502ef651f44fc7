"""The emulated XEP firmware answers byte for byte as the reference says (no pty: bytes in, bytes out)."""

from __future__ import annotations

import numpy as np
import pytest

from app.messages import RangeAxis
from app.sensors.x4m03_codec import DataFloat
from app.sensors.x4m03_parser import X4M03Parser
from sim.radar_firmware import FirmwareConfig, FirmwareFaults, X4M03Firmware


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def ramp(t_s: float, axis: RangeAxis) -> np.ndarray:
    return (np.arange(axis.bins) * 1e-4 + 1j * 2e-4).astype(np.complex64)


@pytest.fixture
def fw() -> X4M03Firmware:
    f = X4M03Firmware(ramp, FirmwareConfig(boot_delay_s=1.0, ready_delay_s=1.0))
    f.power_on(0.0)
    assert f.poll(2.0) == h("7D 30 10 00 00 00 5D 7E") + h("7D 30 11 00 00 00 5C 7E")  # BOOTING, READY
    return f


def test_boot_sends_booting_then_ready_a_second_later_and_pings_say_not_ready_until_then():
    f = X4M03Firmware(ramp, FirmwareConfig(boot_delay_s=1.0, ready_delay_s=1.0))
    f.power_on(0.0)
    assert f.poll(0.99) == b""
    assert f.poll(1.0) == h("7D 30 10 00 00 00 5D 7E")
    assert f.receive(h("7D 01 AE EA AA EE 7C 7E"), 1.5) == h("7D 01 AA EE EA AE 7C 7E")  # PONG not ready
    assert f.poll(2.0) == h("7D 30 11 00 00 00 5C 7E")
    assert f.receive(h("7D 01 AE EA AA EE 7C 7E"), 2.1) == h("7D 01 EA AE EE AA 7C 7E")  # PONG ready


@pytest.mark.parametrize(
    ("command", "reply"),
    [
        ("7D 50 20 0D 7E", "7D 10 6D 7E"),  # x4driver_init → ACK
        ("7D 50 10 21 00 00 00 02 1E 7E", "7D 10 6D 7E"),  # tx_power 2 → ACK
        ("7D 50 10 21 00 00 00 05 19 7E", "7D 20 15 00 00 00 48 7E"),  # tx_power 5 → ERROR 21
        ("7D 20 13 4E 7E", "7D 20 01 00 00 00 5C 7E"),  # set_sensor_mode on XEP → ERROR 1
        ("7D 50 11 26 00 00 00 1A 7E", "7D 11 11 26 00 00 00 00 00 00 00 01 00 00 00 5B 00 00 00 01 7E"),
    ],
)
def test_commands_get_the_reference_replies(fw, command, reply):
    fw.receive(h("7D 50 10 14 00 00 00 CD CC CC 3E 00 00 A0 40 3A 7E"), 3.0)  # frame area 0.4–5.0
    assert fw.receive(h(command), 3.0) == h(reply)


def test_frame_area_is_quantised_and_read_back_with_the_escaped_float(fw):
    assert fw.receive(h("7D 50 10 18 00 00 00 EC 51 38 3E 9E 7E"), 3.0) == h("7D 10 6D 7E")
    assert fw.receive(h("7D 50 10 14 00 00 00 CD CC CC 3E 00 00 A0 40 3A 7E"), 3.0) == h("7D 10 6D 7E")
    assert fw.receive(h("7D 50 11 14 00 00 00 28 7E"), 3.0) == h(
        "7D 11 12 14 00 00 00 00 00 00 00 02 00 00 00 82 82 C5 3E 15 7F 7E A0 40 04 1C 7E"
    )


def test_a_command_with_a_bad_checksum_gets_no_reply_at_all(fw):
    assert fw.receive(h("7D 50 11 14 00 00 00 29 7E"), 3.0) == b""
    assert fw.log.crc_errors == 1
    assert fw.receive(h("7D 50 11 14 00 00 00 28 7E"), 3.0) != b""  # and the device is fine


def test_set_fps_streams_noescape_frames_at_the_measured_rate_and_fps_0_stops(fw):
    fw.receive(h("7D 50 10 14 00 00 00 CD CC CC 3E 00 00 A0 40 3A 7E"), 3.0)
    assert fw.receive(h("7D 50 10 10 00 00 00 00 00 20 41 4C 7E"), 3.0) == h("7D 10 6D 7E")
    wire = fw.poll(3.0 + 10 / 10.032052556 + 1e-6)
    assert wire[:4] == b"\x7c\x7c\x7c\x7c" and len(wire) == 10 * 751
    messages = X4M03Parser().feed(wire)
    assert [m.frame_counter for m in messages] == list(range(1, 11))
    first = messages[0]
    assert isinstance(first, DataFloat) and first.values.size == 182
    assert np.allclose(first.values[:91], np.arange(91) * 1e-4) and np.allclose(first.values[91:], -2e-4)  # Q negated
    assert fw.receive(h("7D 50 10 10 00 00 00 00 00 00 00 2D 7E"), 5.0) == h("7D 10 6D 7E")
    assert fw.poll(10.0) == b""


def test_dropped_frames_advance_the_counter(fw):
    fw.faults.drop_probability = 0.5
    fw.receive(h("7D 50 10 10 00 00 00 00 00 20 41 4C 7E"), 3.0)
    counters = [m.frame_counter for m in X4M03Parser().feed(fw.poll(3.0 + 40.5 / 10.032))]
    assert fw.counter == 40 and fw.log.frames_dropped > 0
    assert len(counters) + fw.log.frames_dropped == 40
    assert counters == sorted(set(counters))  # increasing, with gaps where frames were dropped


def test_module_reset_acks_then_reboots(fw):
    assert fw.receive(h("7D 22 5F 7E"), 3.0) == h("7D 10 6D 7E")
    assert fw.poll(3.4) == b""
    fw.poll(3.5)
    assert not fw.ready
    assert fw.poll(3.5 + 1.0) == h("7D 30 10 00 00 00 5D 7E")
    assert fw.log.boots == 2


def test_downconversion_0_is_not_supported_by_the_emulator(fw):
    assert fw.receive(h("7D 50 10 13 00 00 00 00 2E 7E"), 3.0) == h("7D 20 02 00 00 00 5F 7E")


def test_garbage_fault_puts_random_bytes_before_packets(fw):
    fw.faults = FirmwareFaults(garbage_probability=1.0)
    out = fw.receive(h("7D 50 20 0D 7E"), 3.0)
    parser = X4M03Parser()
    assert len(parser.feed(out)) == 1 and parser.stats.garbage_bytes > 0
