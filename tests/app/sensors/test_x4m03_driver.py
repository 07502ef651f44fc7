"""The real X4M03 driver against the emulator through a real pseudo-terminal (wall-clock time, generous timeouts)."""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import AsyncIterator, Callable

import numpy as np
import pytest

from app.config_yaml import validate_section
from app.errors import ConfigError
from app.messages import RadarFrame
from app.sensors.radar import RadarCommandError, RadarDisconnected, RadarTimeout
from app.sensors.x4m03_commands import X4Param
from app.sensors.x4m03_driver import X4M03Radar
from app.settings import RadarSettings
from sim.radar import RadarEmulator, sea_emulator
from sim.radar_firmware import FirmwareConfig
from sim.radar_track import hover

WAIT_S = 10.0  # generous: the machine may be busy


@pytest.fixture
async def emulator(tmp_path) -> AsyncIterator[RadarEmulator]:
    emu = sea_emulator(
        sea_state=1,
        track=hover(2.0),
        seed=3,
        link_path=str(tmp_path / "x4m03"),
        firmware_config=FirmwareConfig(boot_delay_s=0.0, ready_delay_s=0.05),
    )
    emu.start()
    yield emu
    emu.stop()


def radar_on(emu: RadarEmulator, **kw) -> X4M03Radar:
    return X4M03Radar(RadarSettings(port=emu.path, reconnect_interval_s=0.1, **kw))


async def eventually(check: Callable[[], bool], timeout_s: float = WAIT_S) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while not check():
        assert loop.time() < deadline, "condition not met in time"
        await asyncio.sleep(0.02)


async def frames(radar: X4M03Radar, n: int) -> list[RadarFrame]:
    return [await asyncio.wait_for(radar.next_frame(), WAIT_S) for _ in range(n)]


def after_pings(commands: list[tuple[str, tuple[float, ...]]]) -> list[tuple[str, tuple[float, ...]]]:
    k = 0
    while k < len(commands) and commands[k][0] == "ping":
        k += 1
    return commands[k:]


THESIS_SEQUENCE = [
    ("x4driver_init", ()),
    ("set DOWNCONVERSION", (1.0,)),
    ("set DAC_MIN", (949.0,)),
    ("set DAC_MAX", (1100.0,)),
    ("set ITERATIONS", (16.0,)),
    ("set TX_CENTER_FREQUENCY", (3.0,)),
    ("set TX_POWER", (2.0,)),
    ("set PULSES_PER_STEP", (300.0,)),
    ("set FRAME_AREA_OFFSET", (pytest.approx(0.18),)),
    ("set FRAME_AREA", (pytest.approx(0.4), 5.0)),
    ("get FRAME_AREA", ()),
    ("get FRAME_BIN_COUNT", ()),
]


async def test_init_sequence_sends_the_thesis_settings_in_order_and_reads_back_the_quantised_area(emulator):
    radar = radar_on(emulator)
    axis = await radar.connect()
    try:
        assert axis.bins == 91
        assert axis.start_m == pytest.approx(0.385761, abs=1e-6)
        assert axis.end_m == pytest.approx(5.015391, abs=1e-5)
        assert axis.bin_m == pytest.approx(0.0514403, abs=1e-6)
        assert after_pings(emulator.firmware.log.commands) == THESIS_SEQUENCE
        x4 = emulator.firmware.x4
        assert (x4.dac_min, x4.dac_max, x4.iterations, x4.pulses_per_step, x4.tx_power) == (949, 1100, 16, 300, 2)
    finally:
        await radar.close()


async def test_streaming_gives_consecutive_frames_with_the_sea_echo_in_them(emulator):
    radar = radar_on(emulator)
    await radar.connect()
    try:
        assert await radar.start_streaming() == pytest.approx(10.032052556, rel=1e-6)
        got = await frames(radar, 5)
        counters = [f.frame_counter for f in got]
        assert counters == list(range(counters[0], counters[0] + 5))
        assert all(b.t_s > a.t_s for a, b in itertools.pairwise(got))
        far = got[-1].axis.ranges_m() > 1.2  # beyond the direct path: the sea, 2 m below the vehicle
        peak_m = got[-1].axis.ranges_m()[far][np.argmax(got[-1].amplitude()[far])]
        assert peak_m == pytest.approx(1.92, abs=0.2)  # the antenna sits 8 cm below the reference point
        assert radar.stats.dropped_frames == 0
    finally:
        await radar.close()
    assert emulator.firmware.x4.fps_hz == 0.0  # close stopped the stream


async def test_replies_are_matched_to_their_commands_while_frames_keep_arriving(emulator):
    radar = radar_on(emulator)
    await radar.connect()
    try:
        await radar.start_streaming()
        await frames(radar, 1)
        frames_before = radar.stats.frames
        for _ in range(5):
            assert await radar.get_floats(X4Param.FPS) == pytest.approx((10.032052556,), rel=1e-6)
            assert await radar.get_ints(X4Param.FRAME_BIN_COUNT) == (91,)
            assert await radar.get_ints(X4Param.DAC_MAX) == (1100,)
            await frames(radar, 1)
        assert radar.stats.frames >= frames_before + 5
        assert radar.stats.unexpected_replies == 0
        assert radar.stats.parser.crc_errors == radar.stats.parser.garbage_bytes == 0
    finally:
        await radar.close()


async def test_frame_counter_gaps_are_counted_as_dropped_frames(emulator):
    emulator.faults().drop_probability = 0.3
    radar = radar_on(emulator, queue_size=64)
    await radar.connect()
    try:
        await radar.start_streaming()
        got = await frames(radar, 12)
        counters = [f.frame_counter for f in got]
        gaps = counters[-1] - counters[0] + 1 - len(counters)
        assert gaps > 0
        assert radar.stats.dropped_frames == gaps
    finally:
        await radar.close()


async def test_a_command_corrupted_on_the_wire_gets_no_reply_and_times_out_with_a_clear_error(emulator):
    radar = radar_on(emulator, command_timeout_s=0.3)
    axis = await radar.connect()
    try:
        emulator.faults().corrupt_next_commands = 1
        with pytest.raises(RadarTimeout, match=r"no answer to get FPS within 0.3 s") as info:
            await radar.get_floats(X4Param.FPS)
        assert info.value.command == "get FPS"
        assert emulator.firmware.log.crc_errors == 1
        # nothing changed: the next command is answered, the device configuration is the same
        start_m, end_m = await radar.get_floats(X4Param.FRAME_AREA)
        assert (start_m, end_m) == pytest.approx((axis.start_m, axis.end_m))
        assert radar.stats.command_timeouts == 1
    finally:
        await radar.close()


async def test_a_reply_with_a_bad_checksum_is_dropped_and_counted_and_the_command_times_out(emulator):
    radar = radar_on(emulator, command_timeout_s=0.3)
    await radar.connect()
    try:
        emulator.faults().corrupt_reply_probability = 1.0
        with pytest.raises(RadarTimeout):
            await radar.get_ints(X4Param.ITERATIONS)
        emulator.faults().corrupt_reply_probability = 0.0
        assert radar.stats.parser.crc_errors == 1
        assert await radar.get_ints(X4Param.ITERATIONS) == (16,)
    finally:
        await radar.close()


async def test_a_setting_the_device_refuses_is_a_typed_error_and_changes_nothing(emulator):
    radar = radar_on(emulator)
    await radar.connect()
    try:
        with pytest.raises(RadarCommandError, match="error 21 \\(invalid tx power\\)") as info:
            await radar.set(X4Param.TX_POWER, 7)
        assert info.value.code == 21
        assert emulator.firmware.x4.tx_power == 2
    finally:
        await radar.close()


async def test_garbage_on_the_line_is_skipped_and_counted_and_frames_and_replies_survive(emulator):
    emulator.faults().garbage_probability = 0.5
    radar = radar_on(emulator, queue_size=64)
    await radar.connect()
    try:
        await radar.start_streaming()
        got = await frames(radar, 8)
        assert [f.frame_counter for f in got] == list(range(got[0].frame_counter, got[0].frame_counter + 8))
        assert await radar.get_ints(X4Param.FRAME_BIN_COUNT) == (91,)
        assert radar.stats.parser.garbage_bytes > 0
    finally:
        await radar.close()


async def test_legacy_escaped_frames_are_read_as_well(tmp_path):
    emu = sea_emulator(track=hover(2.0), firmware_config=FirmwareConfig(0.0, 0.05, escaped_frames=True))
    emu.start()
    radar = radar_on(emu)
    try:
        await radar.connect()
        await radar.start_streaming()
        got = await frames(radar, 3)
        assert got[0].baseband.shape == (91,)
    finally:
        await radar.close()
        emu.stop()


async def test_a_slow_reader_gets_the_latest_frames_and_the_drops_are_counted(emulator):
    radar = radar_on(emulator, queue_size=2)
    await radar.connect()
    try:
        await radar.start_streaming()
        await eventually(lambda: radar.stats.frames >= 5)
        assert radar.stats.queue_drops >= 3
        newest = radar.stats.frames  # counters start at 1 and nothing was dropped on the device
        first = await asyncio.wait_for(radar.next_frame(), WAIT_S)
        assert first.frame_counter >= newest - 2
    finally:
        await radar.close()


async def test_unplug_and_replug_recovers_the_stream_and_cancel_stops_it(emulator):
    radar = radar_on(emulator, queue_size=64)
    task = asyncio.create_task(radar.run(), name="radar.run")
    try:
        await frames(radar, 3)
        emulator.unplug()
        await eventually(lambda: radar.stats.disconnects == 1)
        await eventually(lambda: radar.stats.connect_failures >= 2)  # the device is away: attempts fail
        emulator.replug()
        replugged_s = asyncio.get_running_loop().time()
        while (frame := await asyncio.wait_for(radar.next_frame(), WAIT_S)).t_s < replugged_s:
            pass  # drain frames from before the unplug
        assert frame.frame_counter <= 3  # the device rebooted: its counter restarted
        assert radar.stats.connects == 2
        assert emulator.firmware.log.boots == 2
        assert [c for c, _ in emulator.firmware.log.commands].count("x4driver_init") == 2
    finally:
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
    assert emulator.firmware.x4.fps_hz == 0.0  # the cancelled task stopped the stream on its way out


async def test_a_missing_port_is_a_clear_disconnected_error(tmp_path):
    radar = X4M03Radar(RadarSettings(port=str(tmp_path / "nothing-here")))
    with pytest.raises(RadarDisconnected, match="nothing-here: cannot open"):
        await radar.connect()


@pytest.mark.parametrize(
    ("data", "path"),
    [({"tx_power": 7}, "tx_power"), ({"dac_min": 1200}, ""), ({"fps": 10}, "fps"), ({"frame_area_end_m": 0.1}, "")],
)
def test_invalid_settings_are_refused_naming_the_field(data, path):
    with pytest.raises(ConfigError) as info:
        validate_section(RadarSettings, data, "radar")
    assert info.value.path == path
