"""Settings of the X4M03 radar and its driver; defaults are the thesis's (§4.2.2), which are also Novelda's.

Like every settings model (``app/settings.py``): each field has a range and a description naming its unit,
and unknown fields are refused. Load a mapping with :func:`radar_settings` to get a ``ConfigError`` that
names the bad field.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from app.settings import format_validation_error


class X4M03Settings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    port: str = Field("/dev/ttyACM0", description="serial device (USB CDC-ACM 03EB:6124) or a pty path")
    baudrate: int = Field(115200, ge=600, le=10_000_000, description="UART rate (ignored over USB), baud")
    tx_power: int = Field(2, ge=0, le=3, description="0 off, 1 low, 2 medium, 3 high, level")
    dac_min: int = Field(949, ge=0, le=2047, description="DAC sweep minimum, counts")
    dac_max: int = Field(1100, ge=0, le=2047, description="DAC sweep maximum, counts")
    iterations: int = Field(16, ge=1, le=255, description="sweep iterations per frame, count")
    pulses_per_step: int = Field(300, ge=1, le=65535, description="pulses per DAC step, count")
    fps_hz: float = Field(10.0, ge=1.0, le=50.0, description="frame rate requested (the X4 runs 10 as 10.032), Hz")
    frame_area_offset_m: float = Field(0.18, ge=0.0, le=1.0, description="antenna-specific range offset, m")
    frame_area_start_m: float = Field(0.4, ge=-1.0, le=9.8, description="first range wanted, m")
    frame_area_end_m: float = Field(5.0, ge=-1.0, le=9.9, description="last range wanted, m")
    downconversion: Literal[1] = Field(1, description="1 = baseband I/Q (the altitude estimator needs it), flag")
    tx_center_frequency: Literal[3, 4] = Field(3, description="3 = 7.29 GHz, 4 = 8.748 GHz, band")
    prf_div: int | None = Field(None, ge=4, le=255, description="pulse-rate divider; None keeps the board's 16")
    frame_latency_s: float | None = Field(
        None, ge=0.0, le=1.0, description="received → measured; None: half the sweep (24 ms for the thesis), s"
    )
    command_timeout_s: float = Field(2.0, ge=0.05, le=30.0, description="wait for ACK/REPLY (Novelda: 2 s), s")
    init_timeout_s: float = Field(3.0, ge=0.05, le=30.0, description="wait for x4driver_init's ACK (≥ 2 s), s")
    ready_timeout_s: float = Field(5.0, ge=0.1, le=60.0, description="ping until the device is ready, s")
    reconnect_interval_s: float = Field(1.0, ge=0.01, le=60.0, description="pause between reconnect attempts, s")
    queue_size: int = Field(4, ge=1, le=256, description="frames kept for a slow reader (oldest dropped), count")

    @model_validator(mode="after")
    def _ranges_are_ordered(self) -> X4M03Settings:
        if self.dac_min >= self.dac_max:
            raise ValueError(f"dac_min ({self.dac_min}) must be below dac_max ({self.dac_max})")
        if self.frame_area_start_m >= self.frame_area_end_m:
            raise ValueError(
                f"frame_area_start_m ({self.frame_area_start_m}) must be below frame_area_end_m "
                f"({self.frame_area_end_m})"
            )
        return self

    def sweep_s(self) -> float:
        """Time one frame's sweep takes: iterations · pps · (dac_max − dac_min + 1) / PRF, PRF = 243 MHz / prf_div."""
        prf_hz = 243e6 / (self.prf_div if self.prf_div is not None else 16)
        return self.iterations * self.pulses_per_step * (self.dac_max - self.dac_min + 1) / prf_hz


def radar_settings(data: dict[str, Any], source: str = "radar settings") -> X4M03Settings:
    """Validate ``data``; raises ``ConfigError`` naming the field and its allowed range."""
    try:
        return X4M03Settings.model_validate(data)
    except ValidationError as e:
        raise format_validation_error(source, e, X4M03Settings) from e
