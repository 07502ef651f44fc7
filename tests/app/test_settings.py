"""Settings load from YAML; a bad field names its YAML path and allowed range, and nothing loads."""

import pytest

from app.errors import ConfigError
from app.settings import load_settings


def test_default_profile_loads():
    s = load_settings()
    assert s.guidance.setpoint_rate_hz >= 20 and s.connection.url.startswith("udpin://0.0.0.0:")


def test_out_of_range_field_names_path_and_range(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text("envelope:\n  max_horizontal_speed_mps: 40\n")
    with pytest.raises(ConfigError) as e:
        load_settings(p)
    assert e.value.path == "envelope.max_horizontal_speed_mps"
    assert "got 40" in e.value.message and "allowed 0.1..20.0 m/s" in e.value.message


def test_setpoint_rate_below_20_hz_is_refused(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text("guidance:\n  setpoint_rate_hz: 10\n")
    with pytest.raises(ConfigError, match=r"guidance.setpoint_rate_hz: .*allowed 20.0..100.0 Hz"):
        load_settings(p)


def test_misspelt_field_lists_known_fields(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text("runner:\n  tick_hz: 10\n")
    with pytest.raises(ConfigError) as e:
        load_settings(p)
    assert e.value.path == "runner.tick_hz" and "known fields: mode_confirm_timeout_s, tick_rate_hz" in e.value.message


def test_wrong_type_is_reported(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text("telemetry:\n  position_rate_hz: fast\n")
    with pytest.raises(ConfigError, match=r"telemetry.position_rate_hz: .*got 'fast'"):
        load_settings(p)


def test_not_yaml_is_reported(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text("envelope: [unclosed\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_settings(p)


def test_thesis_guidance_profile_turns_the_lead_off():
    from app.settings import SETTINGS_DIR

    s = load_settings(SETTINGS_DIR / "thesis-guidance.yaml")
    assert s.guidance.velocity_lead_s == 0.0 and s.guidance.transient_distance_m == 0.5


def test_default_profile_carries_the_thesis_radar_settings():
    s = load_settings()
    assert (s.radar.tx_power, s.radar.dac_min, s.radar.dac_max, s.radar.iterations) == (2, 949, 1100, 16)
    assert (s.radar.pulses_per_step, s.radar.fps_hz, s.radar.frame_area_offset_m) == (300, 10.0, 0.18)
    assert (s.radar.frame_area_start_m, s.radar.frame_area_end_m) == (0.4, 5.0)
    assert s.radar_altitude.method == "background" and s.radar_altitude.timeout_s == 1.0


@pytest.mark.parametrize(
    ("yaml_text", "path", "fragment"),
    [
        ("radar:\n  tx_power: 7\n", "radar.tx_power", "allowed 0..3 level"),
        ("radar_altitude:\n  clutter_alpha: 1.5\n", "radar_altitude.clutter_alpha", "allowed 0.0..1.0 ratio"),
        ("radar:\n  dac_min: 1200\n", "radar", "dac_min (1200) must be below dac_max (1100)"),
        (
            "guidance:\n  px4:\n    precise_transient_distance_m: 0\n",
            "guidance.px4.precise_transient_distance_m",
            "allowed 0.01..20.0 m",
        ),
        ("guidance:\n  px4:\n    precise_damping_s: 1.5\n", "guidance.px4.precise_damping_s", "allowed 0.0..1.0 s"),
        # A key given twice (YAML would keep the last silently), at any depth:
        ("guidance:\n  exit_zero_s: 0.5\n  exit_zero_s: 5.0\n", "guidance.exit_zero_s", "line 3, first at line 2"),
        ("radar: {}\nradar: {tx_power: 1}\n", "radar", "duplicate key (line 2, first at line 1)"),
    ],
)
def test_a_bad_field_names_its_path(tmp_path, yaml_text, path, fragment):
    p = tmp_path / "s.yaml"
    p.write_text(yaml_text)
    with pytest.raises(ConfigError) as e:
        load_settings(p)
    assert e.value.path == path and fragment in e.value.message


def test_duplicate_state_in_a_mission_is_an_error_naming_it(tmp_path):
    from pathlib import Path

    from app.missions.table import load_mission

    text = (Path(__file__).resolve().parents[2] / "app/missions/circle.yaml").read_text()
    f = tmp_path / "dup.yaml"
    f.write_text(text + "\n  LAND: {terminal: completed}\n")  # a second LAND under states: the last would win
    with pytest.raises(ConfigError) as e:
        load_mission(str(f))
    assert e.value.path == "states.LAND" and "duplicate key" in e.value.message
    # Keys inside lists of mappings are checked too.
    f.write_text(text.replace("{when: vehicle_ready, to: TAKEOFF}", "{when: vehicle_ready, to: TAKEOFF, to: LAND}"))
    with pytest.raises(ConfigError) as e:
        load_mission(str(f))
    assert e.value.path == "states.PREFLIGHT.transitions[0].to"


def test_a_config_error_crosses_to_another_process_as_it_was_raised():
    """An evaluation's worker that meets a bad file hands the error back whole (it was a broken process pool)."""
    import pickle
    from concurrent.futures import ProcessPoolExecutor

    from app.errors import MissionTableError

    with ProcessPoolExecutor(1) as pool:
        error = pool.submit(_raise_config_error).exception()
    assert isinstance(error, ConfigError)
    assert (error.source, error.path, error.message) == ("pickup.yaml", "params.sea_state", "must be 0..5")
    assert str(error) == "pickup.yaml: params.sea_state: must be 0..5"
    table = pickle.loads(pickle.dumps(MissionTableError("m.yaml", "states.X", "unknown state")))
    assert type(table) is MissionTableError and table.path == "states.X"


def _raise_config_error() -> None:
    raise ConfigError("pickup.yaml", "params.sea_state", "must be 0..5")
