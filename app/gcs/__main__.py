"""Ground-station command line: send one command and print its ack, or watch the vehicle.

    python -m app.gcs start --broker mqtt://host:1883 --vehicle-id sea1 [--start-ne N E] [--search-radius M]
    python -m app.gcs abort|hold|resume|rtl|authorize-land --broker URL --vehicle-id ID [--id CMD_ID]
    python -m app.gcs watch --broker URL --vehicle-id ID [--timeout S]

Common: ``[--timeout S] [--username U --password-env VAR] [--ca FILE] [--cert FILE --key FILE]``.

A command is published at QoS 1 on ``seapick/<vehicle>/v1/cmd`` with a fresh id (or ``--id``); the ack
for that id is printed as one JSON line. Exit status: 0 accepted, 1 rejected / no ack within ``--timeout``
/ broker unreachable or refusing us, 2 bad input (one line on stderr). ``watch`` prints every ``state``,
``events`` and ``online`` message as one line, ``<kind> <json>``, until Ctrl-C or ``--timeout``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import secrets
import ssl
import sys
from typing import Any

import aiomqtt
from pydantic import ValidationError

from app.cli import OneLineParser, number, run_cli
from app.errors import ConfigError
from app.gcs.config import GcsSettings
from app.gcs.protocol import COMMAND_NAMES, Ack, Command, MalformedCommand, encode, parse_command
from app.gcs.transport import mqtt_client

PROG = "python -m app.gcs"
COMMANDS = [name.replace("_", "-") for name in COMMAND_NAMES]  # authorize-land on the command line
_OPTION_OF = {
    "broker_url": "--broker",
    "vehicle_id": "--vehicle-id",
    "username": "--username",
    "password_env": "--password-env",
    "ca_file": "--ca",
    "cert_file": "--cert",
    "key_file": "--key",
}


def _parser() -> OneLineParser:
    p = OneLineParser(prog=PROG, description="Send a command to a seapick vehicle over MQTT, or watch it.")
    p.add_argument("command", choices=[*COMMANDS, "watch"])
    p.add_argument("--broker", required=True, help="mqtt://host[:port] or mqtts://host[:port]")
    p.add_argument("--vehicle-id", required=True, help="the vehicle's id in seapick/<id>/v1/…")
    p.add_argument("--id", dest="cmd_id", help="command id (default: a fresh random one)")
    p.add_argument("--timeout", type=number(0.1, 86_400.0, "s"), help="wait this long for the ack (default 10 s)")
    p.add_argument("--username")
    p.add_argument("--password-env", metavar="VAR", help="environment variable holding the password")
    p.add_argument("--ca", help="CA certificate (PEM) for mqtts://")
    p.add_argument("--cert", help="client certificate (PEM) for mutual TLS")
    p.add_argument("--key", help="client key (PEM) for mutual TLS")
    p.add_argument("--start-ne", nargs=2, type=number(-10_000.0, 10_000.0, "m"), metavar=("N", "E"), help="start")
    p.add_argument("--search-radius", type=number(0.1, 5_000.0, "m"), metavar="M", help="start: search radius, m")
    return p


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command != "start" and (args.start_ne is not None or args.search_radius is not None):
        parser.error("--start-ne and --search-radius go with start only")
    settings = _settings(args)
    try:
        password = settings.password()
    except ConfigError as e:
        raise ValueError(f"--password-env: {e.message}") from None
    tls = settings.tls_context()
    try:
        if args.command == "watch":
            return asyncio.run(_watch(settings, password, tls, args.timeout))
        command = _command(args)
        return asyncio.run(_send(settings, password, tls, command, args.timeout or 10.0))
    except KeyboardInterrupt:
        return 0


def _settings(args: argparse.Namespace) -> GcsSettings:
    data: dict[str, Any] = {
        "broker_url": args.broker,
        "vehicle_id": args.vehicle_id,
        "client_id": f"seapick-gcs-{secrets.token_hex(6)}",
        "username": args.username,
        "password_env": args.password_env,
        "ca_file": args.ca,
        "cert_file": args.cert,
        "key_file": args.key,
    }
    try:
        return GcsSettings.from_mapping(data, path="cli")
    except ConfigError as e:
        name = e.path.removeprefix("cli.")
        raise ValueError(f"{_OPTION_OF.get(name, name)}: {e.message}") from None


def _command(args: argparse.Namespace) -> Command:
    """The command the options describe, checked exactly as the vehicle will check it."""
    fields: dict[str, Any] = {"cmd": args.command.replace("-", "_")}
    fields["id"] = args.cmd_id if args.cmd_id is not None else secrets.token_hex(8)
    if args.start_ne is not None:
        fields["start_ne_m"] = list(args.start_ne)
    if args.search_radius is not None:
        fields["search_radius_m"] = args.search_radius
    try:
        return parse_command(json.dumps(fields).encode())
    except MalformedCommand as e:
        raise ValueError(f"--{e.reason}" if e.reason.startswith("id: ") else e.reason) from None


async def _send(
    settings: GcsSettings, password: str | None, tls: ssl.SSLContext | None, command: Command, timeout_s: float
) -> int:
    topics = settings.topics
    try:
        async with asyncio.timeout(timeout_s):
            client = mqtt_client(
                settings, identifier=settings.client_id, password=password, tls_context=tls, clean_start=True
            )
            async with client:
                await client.subscribe(topics.ack, qos=1)
                await client.publish(topics.cmd, encode(command), qos=1)
                async for message in client.messages:
                    ack = _ack(message.payload)
                    if ack is not None and ack.id == command.id:
                        print(ack.model_dump_json(), flush=True)
                        return 0 if ack.accepted else 1
    except TimeoutError:
        print(f"{PROG}: no ack for {command.cmd} id {command.id} within {timeout_s:g} s", file=sys.stderr)
    except aiomqtt.MqttError as e:
        print(f"{PROG}: {settings.broker_url}: {e}", file=sys.stderr)
    return 1


def _ack(payload: Any) -> Ack | None:
    try:
        return Ack.model_validate_json(payload if isinstance(payload, (bytes, str)) else b"")
    except ValidationError:
        return None


async def _watch(
    settings: GcsSettings, password: str | None, tls: ssl.SSLContext | None, timeout_s: float | None
) -> int:
    topics = settings.topics
    kinds = {topics.state: "state", topics.events: "event", topics.online: "online"}
    try:
        async with asyncio.timeout(timeout_s):
            while True:
                client = mqtt_client(
                    settings, identifier=settings.client_id, password=password, tls_context=tls, clean_start=True
                )
                try:
                    async with client:
                        await client.subscribe([(topic, 1) for topic in kinds])
                        async for message in client.messages:
                            payload = message.payload
                            raw = payload if isinstance(payload, bytes) else str(payload or "").encode()
                            text = raw.decode("utf-8", "replace")
                            kind = kinds.get(message.topic.value, message.topic.value)
                            print(f"{kind} {' '.join(text.splitlines())}", flush=True)
                except aiomqtt.MqttError as e:
                    print(f"{PROG}: {settings.broker_url}: {e}; retrying in 1 s", file=sys.stderr, flush=True)
                    await asyncio.sleep(1.0)
    except TimeoutError:
        return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, PROG))
