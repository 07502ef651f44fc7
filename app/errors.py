"""The app's error tree. Adapters translate library errors into these at the boundary (``raise X from e``)."""

from __future__ import annotations


class AppError(Exception):
    """Base of every error the app raises on purpose."""


class ConfigError(AppError):
    """Raised when a settings or mission file is invalid; ``path`` is the YAML path of the bad field."""

    def __init__(self, source: str, path: str, message: str) -> None:
        self.source = source
        self.path = path
        self.message = message
        where = f"{source}: {path}" if path else source
        super().__init__(f"{where}: {message}")

    def __reduce__(self) -> tuple[type[ConfigError], tuple[str, str, str]]:
        # across processes (an evaluation's workers) as it was raised, not as a broken process pool
        return type(self), (self.source, self.path, self.message)


class MissionTableError(ConfigError):
    """Raised when a mission table fails validation at load (before anything connects)."""


class VehicleError(AppError):
    """Raised when the vehicle refuses or fails a command; ``command`` names it, ``result`` says why."""

    def __init__(self, command: str, result: str, detail: str = "") -> None:
        self.command = command
        self.result = result
        self.detail = detail
        super().__init__(f"{command} failed: {result}" + (f" ({detail})" if detail else ""))


class VehicleConnectionError(VehicleError):
    """Raised when no autopilot answers, or what the mission needs (position, home) never arrives in time."""


class CommandRefused(AppError):
    """Raised by the vehicle boundary instead of sending a command that is not ours to send now.

    ``authority`` says who has the vehicle: "pilot" (someone switched the flight mode) or "aborting" (only
    ABORT's own stop may go out).
    """

    def __init__(self, command: str, authority: str) -> None:
        self.command = command
        self.authority = authority
        super().__init__(f"{command} not sent: {authority} has the vehicle")
