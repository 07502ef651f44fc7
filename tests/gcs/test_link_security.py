"""GroundLink with a broker that authenticates (mosquitto_passwd) and one that speaks TLS (a test CA made here)."""

from __future__ import annotations

import asyncio
import logging
import ssl
from pathlib import Path

import aiomqtt
import pytest

from app.gcs.link import GroundLink
from app.gcs.protocol import Topics
from tests.gcs.conftest import Handler, link_settings, observer, running
from tests.gcs.mosquitto import Broker, add_password, make_test_ca

T = Topics("sea1")
ENV = {"SEAPICK_GCS_PASSWORD": "vehicle-secret-7"}


@pytest.fixture
def auth_broker(tmp_path: Path) -> Broker:
    passwords = tmp_path / "passwd"
    add_password(passwords, "uav-login", ENV["SEAPICK_GCS_PASSWORD"])
    add_password(passwords, "operator", "operator-secret")
    b = Broker(tmp_path, password_file=passwords)
    b.start()
    yield b  # type: ignore[misc]
    b.stop()


async def test_only_a_client_with_valid_credentials_gets_a_command_to_the_handler(
    auth_broker: Broker, caplog: pytest.LogCaptureFixture
) -> None:
    """Anonymous and wrong-password clients are refused at connect; the operator's command is handled; the
    link's password appears in no log line."""
    caplog.set_level(logging.DEBUG)
    handler = Handler()
    settings = link_settings(auth_broker, username="uav-login", password_env="SEAPICK_GCS_PASSWORD")
    async with running(GroundLink(settings, handler, environ=ENV)):
        for credentials in ({}, {"username": "operator", "password": "wrong"}, {"username": "nobody"}):
            with pytest.raises(aiomqtt.MqttError, match=r"[Nn]ot authori[sz]ed|[Bb]ad user name or password"):
                async with observer(auth_broker, **credentials) as intruder:
                    await intruder.publish(T.cmd, b'{"cmd":"start","id":"evil"}')
        async with observer(auth_broker, T.ack, username="operator", password="operator-secret") as operator:
            await operator.publish(T.cmd, b'{"cmd":"start","id":"good"}')
            await operator.wait_for(lambda: bool(operator.on(T.ack)))
    assert [c.id for c in handler.received] == ["good"]
    assert operator.json_on(T.ack) == [{"id": "good", "cmd": "start", "accepted": True, "reason": None}]
    assert ENV["SEAPICK_GCS_PASSWORD"] not in caplog.text
    assert "uav-login" not in repr(settings) and "uav-login" not in caplog.text


async def test_a_link_with_a_wrong_password_stays_out_and_keeps_retrying(auth_broker: Broker) -> None:
    """Refused credentials: the link is never connected, and goes on trying with backoff (not a crash)."""
    settings = link_settings(auth_broker, username="uav-login", password_env="SEAPICK_GCS_PASSWORD")
    link = GroundLink(settings, Handler(), environ={"SEAPICK_GCS_PASSWORD": "nope"})
    task = asyncio.create_task(link.run())
    await asyncio.sleep(1.0)
    assert not task.done() and not link.connected and link.counters.connects == 0
    task.cancel()
    await asyncio.gather(task, return_exceptions=True)


@pytest.fixture(scope="module")
def test_ca(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    return make_test_ca(tmp_path_factory.mktemp("ca"))


async def test_tls_with_a_test_ca_carries_commands_and_refuses_an_untrusted_server(
    tmp_path: Path, test_ca: tuple[Path, Path, Path]
) -> None:
    """mqtts:// with the test CA: a command goes through; a client that does not trust the CA cannot connect."""
    ca = test_ca[0]
    broker = Broker(tmp_path, tls=test_ca)
    broker.start()
    handler = Handler()
    trusting = ssl.create_default_context(cafile=str(ca))
    try:
        async with running(GroundLink(link_settings(broker, ca_file=str(ca)), handler)):
            async with observer(broker, T.ack, tls_context=trusting) as obs:
                await obs.publish(T.cmd, b'{"cmd":"rtl","id":"t1"}')
                await obs.wait_for(lambda: bool(obs.on(T.ack)))
            with pytest.raises(aiomqtt.MqttError, match="CERTIFICATE_VERIFY_FAILED"):
                async with observer(broker, tls_context=ssl.create_default_context()):
                    pass
    finally:
        broker.stop()
    assert broker.url.startswith("mqtts://")
    assert [c.id for c in handler.received] == ["t1"]
    assert obs.json_on(T.ack) == [{"id": "t1", "cmd": "rtl", "accepted": True, "reason": None}]
