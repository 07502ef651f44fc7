"""One MQTT v5 connection to the broker in ``GcsSettings`` (the link's and the CLI's).

MQTT v5 because its session semantics are the ones the link needs: a connect with ``clean_start`` drops
whatever a previous run left queued (a stale ``start`` must not fly the vehicle), and ``clean_start=False``
with a session expiry keeps the subscription and the QoS-1 commands the broker queued while we were away.
"""

from __future__ import annotations

import ssl

import aiomqtt
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from app.gcs.config import GcsSettings


def mqtt_client(
    settings: GcsSettings,
    *,
    identifier: str,
    password: str | None,
    tls_context: ssl.SSLContext | None,
    clean_start: bool,
    session_expiry_s: int = 0,
    will: aiomqtt.Will | None = None,
) -> aiomqtt.Client:
    """An ``aiomqtt.Client`` (not yet connected: ``async with`` it) for ``settings``' broker."""
    properties = Properties(PacketTypes.CONNECT)
    properties.SessionExpiryInterval = session_expiry_s
    return aiomqtt.Client(
        settings.host,
        settings.port,
        identifier=identifier,
        username=settings.username,
        password=password,
        protocol=aiomqtt.ProtocolVersion.V5,
        clean_start=clean_start,
        properties=properties,
        will=will,
        keepalive=settings.keepalive_s,
        timeout=settings.connect_timeout_s,
        tls_context=tls_context,
        max_queued_incoming_messages=settings.incoming_queue_size,
    )
