"""Where the ground-station link connects and how: ``GcsSettings``, read from the ``gcs:`` settings section.

``GcsSettings.from_mapping`` validates the section like ``app/settings.py`` validates its own (every field
with a range and a description naming its unit; an invalid value is a ``ConfigError`` naming its dotted
path and the allowed range). The password never sits in the settings: ``password_env`` names the
environment variable that holds it, read by ``password()`` when the link starts. Neither the username nor
the password appears in ``repr``, nor in any log line.
"""

from __future__ import annotations

import os
import re
import ssl
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from app.config_yaml import format_validation_error
from app.errors import ConfigError
from app.gcs.protocol import VEHICLE_ID_PATTERN, Topics

DEFAULT_PORTS = {"mqtt": 1883, "mqtts": 8883}
_ENV_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_CLIENT_ID = re.compile(r"[A-Za-z0-9_.:-]{1,64}")


class _GcsModel(BaseModel):
    """The ``gcs:`` section as written; ``GcsSettings`` is what the app uses."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    broker_url: str = Field(description="mqtt://host[:port] (default 1883) or mqtts://host[:port] (TLS, 8883)")
    vehicle_id: str = Field(description="the vehicle's name in the topic tree seapick/<vehicle_id>/v1/…")
    client_id: str | None = Field(
        None, description="fixed MQTT client id (the broker keeps the session under it); None: seapick-<vehicle_id>"
    )
    username: str | None = Field(None, min_length=1, max_length=256, description="broker username")
    password_env: str | None = Field(None, description="name of the environment variable holding the password")
    ca_file: Path | None = Field(None, description="CA certificate (PEM) the broker's certificate must chain to")
    cert_file: Path | None = Field(None, description="client certificate (PEM) for mutual TLS")
    key_file: Path | None = Field(None, description="client private key (PEM) for mutual TLS")
    keepalive_s: int = Field(15, ge=5, le=600, description="MQTT keepalive: a dead link is noticed within 1.5×, s")
    connect_timeout_s: float = Field(5.0, ge=0.5, le=60.0, description="connect / publish / subscribe timeout, s")
    reconnect_min_s: float = Field(0.2, ge=0.05, le=1.0, description="first reconnect delay (before jitter), s")
    reconnect_max_s: float = Field(
        2.0, ge=0.5, le=4.0, description="reconnect delay cap: the link is back within this of the broker, s"
    )
    session_expiry_s: int = Field(
        600, ge=0, le=86_400, description="the broker keeps our session (queued QoS-1 commands) this long offline, s"
    )
    telemetry_rate_hz: float = Field(2.0, ge=1.0, le=5.0, description="telemetry publish rate, Hz")
    event_queue_size: int = Field(256, ge=1, le=100_000, description="events kept while disconnected, count")
    dedupe_window: int = Field(256, ge=1, le=100_000, description="command ids remembered for duplicates, count")
    incoming_queue_size: int = Field(4096, ge=16, le=100_000, description="received messages not yet read, count")

    @field_validator("broker_url")
    @classmethod
    def _url(cls, value: str) -> str:
        _split_url(value)
        return value

    @field_validator("vehicle_id")
    @classmethod
    def _vehicle(cls, value: str) -> str:
        if not VEHICLE_ID_PATTERN.fullmatch(value):
            raise ValueError("1–64 characters of A–Z, a–z, 0–9, '_' or '-'")
        return value

    @field_validator("client_id")
    @classmethod
    def _client(cls, value: str | None) -> str | None:
        if value is not None and not _CLIENT_ID.fullmatch(value):
            raise ValueError("1–64 characters of A–Z, a–z, 0–9, '_', '.', ':' or '-'")
        return value

    @field_validator("password_env")
    @classmethod
    def _env(cls, value: str | None) -> str | None:
        if value is not None and not _ENV_NAME.fullmatch(value):
            raise ValueError("an environment variable name (letters, digits, '_')")
        return value


def _split_url(url: str) -> tuple[str, str, int]:
    """(scheme, host, port) of a broker URL; ``ValueError`` saying what is wrong."""
    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError as e:
        raise ValueError(f"not a broker URL: {e}") from None
    if parts.scheme not in DEFAULT_PORTS:
        raise ValueError("must start with mqtt:// or mqtts://")
    if parts.username is not None or parts.password is not None:
        raise ValueError("no credentials in the URL (use username and password_env)")
    if not parts.hostname:
        raise ValueError("no host")
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise ValueError("only mqtt[s]://host[:port], no path or query")
    return parts.scheme, parts.hostname, port if port is not None else DEFAULT_PORTS[parts.scheme]


@dataclass(frozen=True)
class GcsSettings:
    """The ground-station link's settings (see ``_GcsModel`` for each field's range and unit)."""

    broker_url: str
    vehicle_id: str
    client_id: str
    username: str | None = field(default=None, repr=False)
    password_env: str | None = None
    ca_file: Path | None = None
    cert_file: Path | None = None
    key_file: Path | None = None
    keepalive_s: int = 15
    connect_timeout_s: float = 5.0
    reconnect_min_s: float = 0.2
    reconnect_max_s: float = 2.0
    session_expiry_s: int = 600
    telemetry_rate_hz: float = 2.0
    event_queue_size: int = 256
    dedupe_window: int = 256
    incoming_queue_size: int = 4096

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], path: str = "gcs", source: str = "settings") -> GcsSettings:
        """Validated settings from a mapping; raises ``ConfigError`` naming ``path.field`` and the allowed range."""
        if not isinstance(data, Mapping):
            raise ConfigError(source, path, f"must be a mapping, got {type(data).__name__}")
        try:
            m = _GcsModel.model_validate(dict(data))
        except ValidationError as e:
            err = format_validation_error(source, e, _GcsModel)
            message = err.message.replace("Value error, ", "", 1)
            raise ConfigError(source, f"{path}.{err.path}" if err.path else path, message) from e

        def bad(name: str, message: str) -> ConfigError:
            return ConfigError(source, f"{path}.{name}", message)

        if m.reconnect_min_s > m.reconnect_max_s:
            raise bad("reconnect_min_s", f"{m.reconnect_min_s} is above reconnect_max_s ({m.reconnect_max_s})")
        tls_files = {"ca_file": m.ca_file, "cert_file": m.cert_file, "key_file": m.key_file}
        if any(tls_files.values()) and not m.broker_url.startswith("mqtts://"):
            name = next(k for k, v in tls_files.items() if v)
            raise bad(name, "TLS files need an mqtts:// broker_url")
        if (m.cert_file is None) != (m.key_file is None):
            raise bad("cert_file" if m.cert_file is None else "key_file", "cert_file and key_file go together")
        for name, file in tls_files.items():
            if file is not None and not file.is_file():
                raise bad(name, f"file not found: {file}")
        if m.password_env is not None and m.username is None:
            raise bad("password_env", "a password needs a username")
        values = m.model_dump()
        values["client_id"] = m.client_id or f"seapick-{m.vehicle_id}"
        return cls(**values)

    @property
    def tls(self) -> bool:
        return self.broker_url.startswith("mqtts://")

    @property
    def host(self) -> str:
        return _split_url(self.broker_url)[1]

    @property
    def port(self) -> int:
        return _split_url(self.broker_url)[2]

    @property
    def topics(self) -> Topics:
        return Topics(self.vehicle_id)

    def password(self, environ: Mapping[str, str] | None = None) -> str | None:
        """The password from the environment variable ``password_env`` (``None`` when none is configured)."""
        if self.password_env is None:
            return None
        env = os.environ if environ is None else environ
        if self.password_env not in env:
            raise ConfigError("environment", "password_env", f"variable {self.password_env} is not set")
        return env[self.password_env]

    def tls_context(self) -> ssl.SSLContext | None:
        """The TLS context for an mqtts:// broker (hostname checked), ``None`` for mqtt://."""
        if not self.tls:
            return None
        try:
            context = ssl.create_default_context(cafile=str(self.ca_file) if self.ca_file else None)
            if self.cert_file is not None:
                context.load_cert_chain(str(self.cert_file), str(self.key_file) if self.key_file else None)
        except (OSError, ssl.SSLError) as e:
            raise ConfigError("tls", "ca_file/cert_file/key_file", f"cannot load: {e}") from e
        return context
