"""The MQTT client of a capture: a thread of its own, a bounded queue, the retained state kept.

    pub = Publisher(spec, report=print); pub.start()
    pub.send(topic, payload, retain)     # the capture's thread: never blocks (a full queue drops, counted)
    pub.close()                          # the end: what is queued goes out (a few seconds at most)

One thread (paho-mqtt driven by hand, `loop()`) connects, publishes and reconnects, so nothing the
broker does reaches the capture: `send` puts the message in a queue of `spec.queue` messages and
returns; a full queue drops it and counts it.  Every retained message's latest payload is kept
(`retained`, one per topic: a register, a unit's health, a discovery config), so the broker's
retained state is whole again after it was away (on each connect the snapshot is published before
what is queued) and a retained value dropped from the queue is sent again once the queue is empty.
A broker that cannot be reached (at the start or later) is one line on stderr per distinct reason
and a retry every 0.5 .. 5 s; the capture goes on.  PREFIX/status is `online` while connected and
`offline` at the end, or as the last will when the connection dies.

What happened to each message is counted: `published` once paho wrote it to the socket (its
on_publish), `dropped` from a full queue, `lost` when the connection died with it handed to paho
but not yet written (paho drops those on reconnecting), `superseded`: a retained value still queued
when the broker came back (the snapshot sends its topic's latest instead), and what is left at the
end "not delivered".  So every message `send` took is counted once: published (the snapshot's and
the stale topics' re-sends are published on top), dropped, lost, superseded or not delivered.
A message written to the socket of a broker that then died is not known to be lost (QoS 0 has no
acknowledgement).  The end (close) takes at most `CLOSE_S` in all: a broker that
accepts and never answers holds it no longer (the last connect's timeout is what is left of it).
"""

from __future__ import annotations

import os
import queue
import ssl
import threading
import time

from sniffer.mqtt.ha import availability
from sniffer.mqtt.options import MqttSpec
from sniffer.stderr import say

BACKOFF_S = (0.5, 5.0)  # retry delays: from, up to (doubling)
CLOSE_S = 5.0  # at the end: at most this long to send what is queued
BATCH = 256  # messages handed to paho between two network passes


class Publisher:
    def __init__(self, spec: MqttSpec, *, report=None, client_id: str | None = None) -> None:
        self.spec = spec
        self.report = report or say
        self.client_id = client_id or f"sniffer-{os.getpid()}-{os.urandom(3).hex()}"
        self.q: queue.Queue = queue.Queue(max(1, spec.queue))
        self.retained: dict[str, bytes] = {}
        self.stale: set[str] = set()  # retained topics whose latest message was dropped: sent again later
        self.published = 0  # written to the socket (on_publish)
        self.dropped = 0  # a full queue
        self.lost = 0  # handed to paho, not yet written when the connection died
        self.superseded = 0  # retained values queued while the broker was away: its latest went in their place
        self._unwritten = 0  # handed to paho and not yet written (on this connection)
        self.connects = 0
        self.connected = False
        self.last_error: str | None = None
        self._closing = threading.Event()
        self._thread: threading.Thread | None = None
        self._client = None
        self._ready = False  # CONNACK accepted
        self._refused: str | None = None
        self._said: set[str] = set()
        self._finishing = False

    # ------------------------------------------------------------ the capture's side
    def send(self, topic: str, payload: bytes, retain: bool) -> None:
        """Queue a message; never blocks.  A full queue drops it (a retained one is sent again later)."""
        if retain:
            self.retained[topic] = payload
        try:
            self.q.put_nowait((topic, payload, retain))
        except queue.Full:
            self.dropped += 1
            if retain:
                self.stale.add(topic)

    def status(self) -> dict:
        return {"broker": self.spec.broker, "prefix": self.spec.prefix, "tls": self.spec.tls,
                "connected": self.connected, "published": self.published, "queued": self.q.qsize(),
                "queue_max": self.spec.queue, "dropped": self.dropped, "lost": self.lost,
                "superseded": self.superseded,
                "retained": len(self.retained),
                "connects": self.connects, "last_error": self.last_error}

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="mqtt", daemon=True)
        self._thread.start()

    def close(self, timeout: float = CLOSE_S) -> None:
        """Send what is queued (for at most `timeout` s in all), mark PREFIX/status offline, disconnect."""
        self._close_by = time.monotonic() + timeout
        self._closing.set()
        if self._thread is not None:
            self._thread.join(max(0.0, self._close_by - time.monotonic()) + 0.5)  # the thread ends by _close_by
        left = self.q.qsize() + self._unwritten + len(self.stale)  # stale: a retained topic's latest not sent again
        if self.connects or left or self.dropped or self.lost or self.superseded:
            self.report(f"mqtt: {self.published} messages published to {self.spec.broker}"
                        + (f", {self.dropped} dropped (queue full)" if self.dropped else "")
                        + (f", {self.superseded} retained values superseded while the broker was away (their "
                           "topics' latest sent instead)" if self.superseded else "")
                        + (f", {self.lost} lost with the connection (handed over, not yet sent when the broker "
                           "went)" if self.lost else "")
                        + (f", {left} not delivered ({self.last_error or 'not connected'})" if left else ""))

    # ------------------------------------------------------------ the client's thread
    def _make_client(self):
        import paho.mqtt.client as mqtt

        c = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=self.client_id, protocol=mqtt.MQTTv311)
        c.connect_timeout = 5.0
        if self.spec.username:
            c.username_pw_set(self.spec.username, self.spec.password)
        ctx = self.spec.tls_context()
        if ctx is not None:
            c.tls_set_context(ctx)
        c.will_set(availability(self.spec.prefix), b"offline", qos=1, retain=True)
        c.on_connect = self._on_connect
        c.on_publish = self._on_publish
        return c

    def _on_publish(self, client, userdata, mid, reason_code, properties) -> None:
        """A QoS 0 message written to the socket (the offline mark, QoS 1: acknowledged)."""
        self.published += 1
        self._unwritten = max(0, self._unwritten - 1)

    def _connection_died(self) -> None:
        """What paho held unwritten is gone (reconnect() drops QoS 0 messages): counted as lost."""
        self.lost += self._unwritten
        self._unwritten = 0

    def _on_connect(self, client, userdata, flags, reason_code, properties) -> None:
        if reason_code.is_failure:
            self._refused = str(reason_code)
        else:
            self._ready = True

    def _run(self) -> None:
        try:
            self._client = self._make_client()
        except Exception as e:  # noqa: BLE001 - a client that cannot be made: said once, the capture goes on
            self.last_error = str(e)
            self.report(f"error: mqtt: {e}")
            return
        delay = BACKOFF_S[0]
        while not self._closing.is_set():
            if not self._connect():
                if self._closing.wait(delay):
                    break
                delay = min(delay * 2, BACKOFF_S[1])
                continue
            delay = BACKOFF_S[0]
            self._serve()
        self._finish()

    def _connect(self) -> bool:
        """Open the connection and wait for the broker's answer; False (said once per reason) if it fails."""
        c, self._ready, self._refused, lost = self._client, False, None, False
        self._connection_died()
        by = getattr(self, "_close_by", None) if self._closing.is_set() or self._finishing else None
        if by is not None:  # the end: the socket's connect may take what is left of CLOSE_S, no more
            if by - time.monotonic() < 0.05:
                return self._failed(self.last_error or "no time left to connect")
            c.connect_timeout = min(5.0, by - time.monotonic())
        try:
            if self.connects or self.last_error:
                c.reconnect()
            else:
                c.connect(self.spec.host, self.spec.port, keepalive=30)
            deadline = time.monotonic() + c.connect_timeout
            while not self._ready and self._refused is None and time.monotonic() < deadline:
                if self._closing.is_set():  # the capture ended meanwhile: wait only as long as closing may
                    deadline = min(deadline, getattr(self, "_close_by", deadline))
                rc = c.loop(0.05)
                if not _ok(rc) and not self._ready:
                    lost = True
                    break
        except (OSError, ValueError) as e:  # refused, unreachable, DNS, TLS (ssl errors are OSErrors)
            return self._failed(_reason(e))
        if not self._ready:
            return self._failed(f"the broker refused the connection: {self._refused}" if self._refused
                                else "the broker closed the connection before accepting it"
                                + (" (does it want a client certificate? --mqtt-cert)" if self.spec.tls
                                   and not self.spec.cert else "") if lost
                                else "no answer from the broker")
        again = self.connects > 0 or self.last_error is not None
        n = self._resync()
        self.connects += 1
        self.connected = True
        self.last_error = None
        self._said.clear()
        self.report(f"mqtt: {'reconnected' if again else 'connected'} to {self.spec.broker}"
                    + (f" ({n} retained values published again)" if again else
                       f", publishing under {self.spec.prefix}/"))
        return True

    def _failed(self, why: str) -> bool:
        self.connected = False
        self.last_error = why
        if why not in self._said:
            self._said.add(why)
            self.report(f"mqtt: cannot connect to {self.spec.broker}: {why}; retrying (the capture goes on)")
        try:
            self._client.disconnect()
        except Exception:  # noqa: BLE001 - the socket may never have been opened
            pass
        return False

    def _resync(self) -> int:
        """On (re)connecting: `online`, every retained value as it is now, then the queued events."""
        events = []
        for item in self._drain():
            if not item[2]:
                events.append(item)
            else:  # an older (or the same) value of a topic the snapshot sends as it is now: not sent itself
                self.superseded += 1
        self.stale.clear()
        snapshot = self.retained.copy()
        self._publish(availability(self.spec.prefix), b"online", True)
        for topic, payload in snapshot.items():
            self._publish(topic, payload, True)
        for item in events:
            self._publish(*item)
        return len(snapshot)

    def _serve(self) -> None:
        """Connected: hand queued messages to paho while its buffer is empty; return when the link is lost."""
        import paho.mqtt.client as mqtt

        c = self._client
        while not self._closing.is_set():
            busy = False
            if not c.want_write():
                busy = self._hand_over(BATCH)
            rc = c.loop(0.0 if busy else 0.05)
            if not _ok(rc):
                self._connection_died()
                self.connected = False
                self.last_error = f"connection lost ({mqtt.error_string(rc).rstrip('.')})"
                self.report(f"mqtt: lost the connection to {self.spec.broker}; reconnecting "
                            "(the capture goes on, retained values are kept)")
                self._said.add(self.last_error)
                return

    def _hand_over(self, n: int) -> bool:
        if self._finishing and self.stale:  # the end: the broker's retained state first (_collapse_queue)
            self._send_stale(n)
            return True
        for _ in range(n):
            try:
                item = self.q.get_nowait()
            except queue.Empty:
                break
            self._publish(*item)
        else:
            return True
        if self.stale:  # retained values dropped from a full queue: their latest, now there is room
            self._send_stale(n)
            return True
        return False

    def _send_stale(self, n: int) -> None:
        """Up to `n` retained topics whose latest value was not sent (dropped, lost): that latest, now."""
        for _ in range(min(n, len(self.stale))):
            topic = self.stale.pop()
            self._publish(topic, self.retained[topic], True)

    def _drain(self) -> list:
        """Everything queued, in order, taken out of the queue."""
        items = []
        while True:
            try:
                items.append(self.q.get_nowait())
            except queue.Empty:
                return items

    def _collapse_queue(self) -> None:
        """The end, before what is left goes out: every retained topic still queued (or dropped earlier) is sent
        once, as its latest value and first; the events after it, in their order.  The time the end may take is
        bounded (CLOSE_S): on a busy machine it went on the older queued values of a topic and the broker kept
        one of them, not the capture's last."""
        events = []
        for item in self._drain():
            if item[2]:
                self.stale.add(item[0])
            else:
                events.append(item)
        for item in events:  # room: they came out of it, and nothing is queued any more at the end
            self.q.put_nowait(item)

    def _publish(self, topic: str, payload: bytes, retain: bool) -> None:
        info = self._client.publish(topic, payload, qos=0, retain=retain)
        if info.rc == 0:
            self._unwritten += 1  # published once written (_on_publish)
        else:  # paho refused it (not connected): lost with the connection
            self.lost += 1
            if retain:
                self.stale.add(topic)

    def _finish(self) -> None:
        """The end: what is queued goes out while the broker is there (until the deadline), then offline."""
        c = self._client
        if c is None:
            return
        by = getattr(self, "_close_by", time.monotonic() + CLOSE_S)
        self._finishing = True
        if not self.connected:  # one more try: the broker may be back, and the final state is worth it
            self._closing.clear()
            try:
                if not self._connect():
                    return
            finally:
                self._closing.set()
        self._collapse_queue()
        try:
            while time.monotonic() < by and (self.q.qsize() or self.stale or c.want_write()):
                if not c.want_write():
                    self._hand_over(BATCH)
                if not _ok(c.loop(0.01)):
                    self._connection_died()
                    return
            info = c.publish(availability(self.spec.prefix), b"offline", qos=1, retain=True)
            self._unwritten += info.rc == 0  # the offline mark: counted published when acknowledged
            while time.monotonic() < by and not info.is_published():
                if not _ok(c.loop(0.01)):
                    self._connection_died()
                    return
            c.disconnect()
            c.loop(0.01)
        except (OSError, ValueError, RuntimeError):
            pass
        finally:
            self.connected = False


def _ok(rc) -> bool:
    """A pass of paho's loop that left the connection up (AGAIN: TLS read a record without MQTT data)."""
    return rc in (0, -1)  # MQTT_ERR_SUCCESS, MQTT_ERR_AGAIN


def _reason(e: Exception) -> str:
    if isinstance(e, ssl.SSLError):
        return f"TLS: {getattr(e, 'verify_message', None) or e.reason or e}"
    return getattr(e, "strerror", None) or str(e) or type(e).__name__


__all__ = ["Publisher"]
