"""GcsSettings from a settings mapping: defaults, errors naming the dotted path and range, secrets kept out."""

from __future__ import annotations

from pathlib import Path

import pytest

from app.errors import ConfigError
from app.gcs.config import GcsSettings

BASE = {"broker_url": "mqtt://broker.local", "vehicle_id": "sea1"}


def test_defaults_and_derived_values() -> None:
    """Port from the scheme, a fixed client id from the vehicle id, telemetry at 2 Hz."""
    s = GcsSettings.from_mapping(BASE)
    assert (s.host, s.port, s.tls, s.client_id) == ("broker.local", 1883, False, "seapick-sea1")
    assert s.telemetry_rate_hz == 2.0 and s.topics.cmd == "seapick/sea1/v1/cmd"
    assert GcsSettings.from_mapping({**BASE, "broker_url": "mqtts://[::1]"}).port == 8883
    assert GcsSettings.from_mapping({**BASE, "broker_url": "mqtt://h:1999"}).port == 1999


@pytest.mark.parametrize(
    ("override", "path", "message"),
    [
        ({"telemetry_rate_hz": 10}, "gcs.telemetry_rate_hz", "allowed 1.0..5.0 Hz"),
        ({"reconnect_max_s": 30}, "gcs.reconnect_max_s", "allowed 0.5..4.0 s"),
        ({"keepalive_s": 1}, "gcs.keepalive_s", "allowed 5..600 s"),
        ({"broker_url": "http://h"}, "gcs.broker_url", "must start with mqtt:// or mqtts://"),
        ({"broker_url": "mqtt://u:p@h"}, "gcs.broker_url", "no credentials in the URL"),
        ({"broker_url": "mqtt://h:99999"}, "gcs.broker_url", "not a broker URL"),
        ({"broker_url": "mqtt://h/x"}, "gcs.broker_url", "no path"),
        ({"vehicle_id": "a/b"}, "gcs.vehicle_id", "1–64 characters"),
        ({"password_env": "NOT-A-NAME"}, "gcs.password_env", "environment variable name"),
        ({"password": "hunter2"}, "gcs.password", "unknown field"),
        ({"reconnect_min_s": 1.0, "reconnect_max_s": 0.5}, "gcs.reconnect_min_s", "above reconnect_max_s"),
        ({"ca_file": "ca.pem"}, "gcs.ca_file", "TLS files need an mqtts:// broker_url"),
        ({"broker_url": "mqtts://h", "ca_file": "/no/such/ca.pem"}, "gcs.ca_file", "file not found"),
        ({"password_env": "X"}, "gcs.password_env", "a password needs a username"),
    ],
)
def test_a_bad_value_is_an_error_naming_its_path(override: dict[str, object], path: str, message: str) -> None:
    """The ConfigError names the dotted path and says what is allowed."""
    with pytest.raises(ConfigError) as caught:
        GcsSettings.from_mapping({**BASE, **override})
    assert caught.value.path == path
    assert message in caught.value.message


def test_the_path_prefix_is_the_callers() -> None:
    """Nested deeper in a settings file, the error says where."""
    with pytest.raises(ConfigError, match=r"vehicle\.yaml: links\.gcs\.telemetry_rate_hz"):
        GcsSettings.from_mapping({**BASE, "telemetry_rate_hz": 0}, path="links.gcs", source="vehicle.yaml")


def test_credentials_stay_out_of_repr_and_come_from_the_environment(tmp_path: Path) -> None:
    """The username is not in repr, the password is not in the settings at all; a missing variable is named."""
    s = GcsSettings.from_mapping({**BASE, "username": "pilot-login", "password_env": "GCS_PW"})
    assert "pilot-login" not in repr(s)
    assert s.password({"GCS_PW": "s3cret"}) == "s3cret"
    assert "s3cret" not in repr(s)
    with pytest.raises(ConfigError, match="variable GCS_PW is not set"):
        s.password({})
