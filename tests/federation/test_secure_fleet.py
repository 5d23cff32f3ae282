"""Must show (issue 7): with the generated secure mosquitto config, only the fleet's roles get in, each writes
only its own topics, and the run gives the same numbers as on the local bus."""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from fleetrl.federation.wire.signing import FleetKey
from fleetrl.federation.wire.topics import chief_topic, worker_topic
from fleetrl.runs.secure import SecureFleet, write_secure_config
from fleetrl.transport.base import Transport
from fleetrl.transport.broker import EmbeddedBroker, free_port
from fleetrl.transport.local import LocalBus
from fleetrl.transport.mqtt import MqttTransport

pytestmark = [
    pytest.mark.mqtt,
    pytest.mark.timeout(90),
    pytest.mark.mosquitto,
]


@pytest.fixture(scope="module")
def secure() -> Iterator[tuple[SecureFleet, EmbeddedBroker]]:
    # not pytest's tmp_path (private to root): mosquitto, dropped to its own user, must reach the files
    with tempfile.TemporaryDirectory(prefix="fleetrl-secure-") as name:
        directory = Path(name)
        fleet = write_secure_config(
            directory, workers=["1", "2", "3"], port=free_port(), self_signed_tls=True
        )
        with EmbeddedBroker("mosquitto", port=fleet.port, config=fleet.config) as broker:
            yield fleet, broker


def transport(fleet: SecureFleet, user: str, password: str | None = None) -> MqttTransport:
    url = fleet.url(user) if password is None else f"mqtts://{user}:{password}@{fleet.host}:{fleet.port}"
    return MqttTransport(url, ca_file=str(fleet.ca_file), reconnect_delay=(1, 2))


@pytest.mark.parametrize(
    "url",
    ["mqtts://{host}:{port}", "mqtts://1:wrong@{host}:{port}", "mqtts://nobody:x@{host}:{port}"],
    ids=["anonymous", "wrong password", "unknown user"],
)
def test_strangers_cannot_connect(secure: tuple[SecureFleet, EmbeddedBroker], url: str) -> None:
    fleet, _ = secure
    client = MqttTransport(url.format(host=fleet.host, port=fleet.port), ca_file=str(fleet.ca_file))
    with pytest.raises(ConnectionError, match="cannot connect"):
        client.connect("stranger", timeout=5)


def test_plain_tcp_is_refused_by_the_tls_listener(secure: tuple[SecureFleet, EmbeddedBroker]) -> None:
    fleet, _ = secure
    with pytest.raises(ConnectionError):
        MqttTransport(f"mqtt://chief:{fleet.passwords['chief']}@{fleet.host}:{fleet.port}").connect(
            "plain", timeout=1
        )


def test_acl_keeps_a_worker_to_its_own_topic(secure: tuple[SecureFleet, EmbeddedBroker]) -> None:
    fleet, _ = secure
    chief, one = transport(fleet, "chief"), transport(fleet, "1")
    chief.connect("acl-chief", timeout=10)
    one.connect("acl-1", timeout=10)
    try:
        chief.subscribe(worker_topic("acl", "2").rsplit("/", 1)[0] + "/+")
        one.subscribe(chief_topic("acl"))
        time.sleep(0.3)
        one.publish(worker_topic("acl", "2"), b"impersonating 2")  # dropped by the ACL
        one.publish(chief_topic("acl"), b"pretending to be the chief")  # dropped by the ACL
        one.publish(worker_topic("acl", "1"), b"own topic")  # allowed
        got = chief.receive(5)
        assert got is not None and got.payload == b"own topic"
        assert chief.receive(0.5) is None and one.receive(0.5) is None
    finally:
        chief.close()
        one.close()


def test_a_secure_signed_run_matches_the_local_bus(
    secure: tuple[SecureFleet, EmbeddedBroker],
    fleet_runner: Callable[..., Any],
    fake_fleet: Callable[..., dict[str, Any]],
) -> None:
    fleet, _ = secure
    key = FleetKey.from_file(fleet.key_file)
    local = fleet_runner(LocalBus().client, fake_fleet(), max_rounds=10)

    def role_transport(role: str) -> Transport:
        return transport(fleet, role)

    remote = fleet_runner(
        None,
        fake_fleet(),
        run_id="secure",
        max_rounds=10,
        role_transport=role_transport,
        chief_kwargs={"key": key},
        worker_kwargs={"key": key},
    )
    assert remote.records == local.records
    assert remote.chief.rejections == {}
