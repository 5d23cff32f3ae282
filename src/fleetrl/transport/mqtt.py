"""A :class:`~fleetrl.transport.base.Transport` over MQTT 3.1.1 with paho-mqtt 2.x: TCP_NODELAY on every
connection (docs/protocol.md), reconnection with backoff, subscriptions renewed on every connect."""

from __future__ import annotations

import dataclasses
import logging
import os
import queue
import socket
import ssl
import threading
import time
from dataclasses import dataclass
from typing import Any
from urllib.parse import unquote, urlsplit

import paho.mqtt.client as paho
from paho.mqtt.enums import CallbackAPIVersion

from fleetrl.transport.base import Received, Will
from fleetrl.transport.login import broker_password

log = logging.getLogger(__name__)

CONNECT_LOG_INTERVAL = 10.0  # seconds between log lines while connect waits for an unreachable broker


@dataclass(frozen=True)
class BrokerAddress:
    """Where a broker is and how to log in, parsed from ``mqtt://[user:pass@]host[:port]`` or ``mqtts://…``."""

    host: str
    port: int
    tls: bool = False
    username: str | None = None
    password: str | None = None

    @classmethod
    def parse(cls, url: str) -> BrokerAddress:
        """Parse a broker URL; ValueError saying what is wrong otherwise."""
        parts = urlsplit(url)
        if parts.scheme not in ("mqtt", "mqtts"):
            raise ValueError(f"bad broker URL {url!r}: use mqtt://[user@]host:port or mqtts://…")
        if not parts.hostname:
            raise ValueError(f"bad broker URL {url!r}: no host")
        tls = parts.scheme == "mqtts"
        try:
            port = parts.port or (8883 if tls else 1883)
        except ValueError:
            raise ValueError(f"bad broker URL {url!r}: bad port") from None
        username = unquote(parts.username) if parts.username else None
        password = unquote(parts.password) if parts.password else None
        return cls(parts.hostname, port, tls, username, password)

    @property
    def url(self) -> str:
        """The URL without credentials (safe to log)."""
        return f"{'mqtts' if self.tls else 'mqtt'}://{self.host}:{self.port}"


class MqttTransport:
    """An MQTT client implementing :class:`~fleetrl.transport.base.Transport`.

    :param ca_file: CA certificate file for ``mqtts`` (None: the system's CAs)
    :param keepalive: seconds; the broker publishes the will after 1.5× this of silence
    :param clean_session: False asks the broker to keep the session across disconnects (the federation
        roles); a device link must not receive commands queued while it was away
    :param password: replaces one in ``url``; without either, a URL naming a user takes
        ``FLEETRL_BROKER_PASSWORD`` from the environment
    """

    def __init__(
        self,
        url: str,
        *,
        ca_file: str | None = None,
        keepalive: int = 30,
        reconnect_delay: tuple[int, int] = (1, 30),
        clean_session: bool = True,
        cert_file: str | None = None,
        key_file: str | None = None,
        connect_timeout: float = 10.0,
        password: str | None = None,
    ) -> None:
        self.address = BrokerAddress.parse(url)
        if password is None and self.address.username is not None and self.address.password is None:
            password = broker_password(None)  # FLEETRL_BROKER_PASSWORD, if set
        if password is not None:
            self.address = dataclasses.replace(self.address, password=password)
        self.connect_timeout = connect_timeout
        self.keepalive = keepalive
        self._tls: dict[str, Any] = {"ca_certs": ca_file, "certfile": cert_file, "keyfile": key_file}
        self._reconnect_delay = reconnect_delay
        self._clean_session = clean_session
        self._queue: queue.Queue[Received] = queue.Queue()
        self._filters: dict[str, int] = {}
        self._announced: dict[str, bytes] = {}
        self._lock = threading.Lock()
        self._connected = threading.Event()
        self._refused: str | None = None
        self._unacked: list[paho.MQTTMessageInfo] = []
        self._client: paho.Client | None = None
        self.connection_losses = 0  # after it was made (a chief's lease is in doubt after one)

    @property
    def connected(self) -> bool:
        """Whether the connection is up now (the broker acknowledged it and it was not lost since)."""
        return self._connected.is_set() and self._refused is None

    def connect(self, client_id: str, *, will: Will | None = None, timeout: float | None = None) -> None:
        """Connect as ``client_id`` and start the network thread; ConnectionError at once for a refused login,
        after ``timeout`` s (default ``connect_timeout``) of retries for an unreachable broker."""
        timeout = self.connect_timeout if timeout is None else timeout
        client = paho.Client(
            CallbackAPIVersion.VERSION2,
            client_id=client_id,
            protocol=paho.MQTTv311,
            clean_session=self._clean_session,
        )
        if self.address.username is not None:
            client.username_pw_set(self.address.username, self.address.password)
        if self.address.tls:
            client.tls_set(**self._tls, cert_reqs=ssl.CERT_REQUIRED)
        if will is not None:
            client.will_set(will.topic, will.payload, qos=will.qos, retain=will.retain)
        client.reconnect_delay_set(*self._reconnect_delay)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        self._client = client
        client.connect_async(self.address.host, self.address.port, keepalive=self.keepalive)
        client.loop_start()
        if not self._wait_connected(timeout) or self._refused:
            self._shutdown()
            if self._refused:
                refused = f"the broker refused the login: {self._refused}"
                raise ConnectionError(f"cannot connect to {self.address.url} as {client_id!r}: {refused}")
            raise ConnectionError(
                f"cannot reach the broker {self.address.url} as {client_id!r}: no answer within {timeout:g} s"
            )

    def _wait_connected(self, timeout: float) -> bool:
        started = time.monotonic()
        deadline = started + timeout
        while not self._connected.wait(min(CONNECT_LOG_INTERVAL, max(0.0, deadline - time.monotonic()))):
            waited = time.monotonic() - started
            if waited >= timeout:
                return False
            log.info(
                "still trying to reach the broker %s (%.0f s of %g s; retrying with backoff)",
                self.address.url, waited, timeout,
            )  # fmt: skip
        return True

    def publish(self, topic: str, payload: bytes, *, qos: int = 1, retain: bool = False) -> None:
        """Publish (QoS 1 by default); queued by paho while disconnected."""
        client = self._require()
        info = client.publish(topic, payload, qos=qos, retain=retain)
        if info.rc not in (paho.MQTT_ERR_SUCCESS, paho.MQTT_ERR_NO_CONN):
            raise ConnectionError(f"publish to {topic} failed: {paho.error_string(info.rc)}")
        if qos > 0:
            with self._lock:
                self._unacked = [i for i in self._unacked if not _settled(i)]
                self._unacked.append(info)

    def announce(self, topic: str, payload: bytes) -> None:
        with self._lock:
            self._announced[topic] = payload
        self.publish(topic, payload, retain=True)

    def subscribe(self, topic_filter: str, *, qos: int = 1) -> None:
        """Subscribe now and again after every reconnect."""
        client = self._require()
        with self._lock:
            self._filters[topic_filter] = qos
        if self._connected.is_set():
            client.subscribe(topic_filter, qos=qos)

    def receive(self, timeout: float | None = None) -> Received | None:
        try:
            return self._queue.get(timeout=timeout)
        except queue.Empty:
            return None

    def close(self, flush_timeout: float = 5.0) -> None:
        """Wait up to ``flush_timeout`` s for QoS 1 messages to be acknowledged, then disconnect (no will)."""
        if self._client is None:
            return
        with self._lock:
            unacked = list(self._unacked)
        for info in unacked:
            try:
                info.wait_for_publish(flush_timeout)
            except (RuntimeError, ValueError):  # paho raises if the message can no longer be sent
                break
        self._client.disconnect()
        self._shutdown()

    def _shutdown(self) -> None:
        if self._client is not None:
            self._client.loop_stop()
            self._client = None
        self._connected.clear()

    def _require(self) -> paho.Client:
        if self._client is None:
            raise ConnectionError("not connected: call connect() first")
        return self._client

    def _on_connect(
        self, client: paho.Client, userdata: Any, flags: Any, reason: Any, properties: Any
    ) -> None:
        if reason.is_failure:
            self._refused = str(reason)
            log.warning("broker %s refused the connection: %s", self.address.url, reason)
            self._connected.set()
            return
        sock = client.socket()
        if isinstance(sock, socket.socket):  # also true of ssl.SSLSocket
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self._lock:
            filters = list(self._filters.items())
            announced = list(self._announced.items())
        for topic_filter, qos in filters:
            client.subscribe(topic_filter, qos=qos)
        for topic, payload in announced:
            client.publish(topic, payload, qos=1, retain=True)
        self._connected.set()

    def _on_disconnect(
        self, client: paho.Client, userdata: Any, flags: Any, reason: Any, properties: Any
    ) -> None:
        self._connected.clear()
        if self._client is not None:
            self.connection_losses += 1
        if self._client is not None and reason.is_failure:
            log.warning("lost connection to %s (%s); reconnecting with backoff", self.address.url, reason)

    def _on_message(self, client: paho.Client, userdata: Any, message: paho.MQTTMessage) -> None:
        self._queue.put(Received(message.topic, bytes(message.payload), retained=bool(message.retain)))


def probe_broker(url: str, *, timeout: float, **options: Any) -> None:
    """Connect to the broker at ``url`` and leave; ConnectionError if that fails within ``timeout`` s."""
    transport = MqttTransport(url, connect_timeout=timeout, **options)
    transport.connect(f"fleetrl-probe-{os.getpid()}-{time.monotonic_ns() % 10**6}")
    transport.close()


RETAINED_GRACE = 0.5  # seconds to wait after a SUBACK (a retained message follows it at once)


def read_retained(url: str, topic: str, *, client_id: str, timeout: float, **options: Any) -> bytes | None:
    """The message retained on ``topic`` (None: none came ``RETAINED_GRACE`` s after the SUBACK), read over
    a clean-session connection of its own; ConnectionError if that fails within ``timeout`` s."""
    transport = MqttTransport(url, connect_timeout=timeout, clean_session=True, **options)
    acked = threading.Event()
    transport.connect(client_id)
    try:
        client = transport._require()
        client.on_subscribe = lambda *_: acked.set()
        result, _ = client.subscribe(topic, qos=1)
        if result != paho.MQTT_ERR_SUCCESS:
            raise ConnectionError(
                f"cannot read {topic} on {transport.address.url}: {paho.error_string(result)}"
            )
        deadline = time.monotonic() + timeout
        acked_at: float | None = None
        while True:
            now = time.monotonic()
            if acked_at is None and acked.is_set():
                acked_at = now
            if acked_at is not None and now >= acked_at + RETAINED_GRACE:
                return None
            if now >= deadline:
                raise ConnectionError(
                    f"cannot read {topic} on {transport.address.url}: no SUBACK within {timeout:g} s"
                )
            received = transport.receive(0.05)
            if received is not None and received.topic == topic and received.retained:
                return received.payload or None  # an empty retained message is none
    finally:
        transport.close(flush_timeout=0.5)


def _settled(info: paho.MQTTMessageInfo) -> bool:
    """Whether a QoS 1 publish needs no more waiting: acknowledged, or queued while disconnected."""
    try:
        return info.is_published()
    except (RuntimeError, ValueError):
        return True
