"""MQTT: what a broker outage costs is counted, and a broker that never answers cannot hold the end up.

The client (sniffer/mqtt/client.py) against a real mosquitto (tests/broker.py) that is frozen
(SIGSTOP: the socket fills, paho holds what it cannot write) and then killed: what paho held is
lost with the connection, and the summary and the status say how many; nothing is counted
published that was not written.  A socket server that accepts and never answers: close() ends the
client's thread within its time (the docs' 5 s), not after a connect of its own 5 s.
"""

from __future__ import annotations

import os
import signal
import socket
import time
from dataclasses import replace

from broker import Subscriber

from sniffer.mqtt.client import Publisher
from sniffer.mqtt.options import parse_url

PAYLOAD = b"x" * 16_384
SENT = 2_000  # 32 MB: more than the loopback socket's buffers hold, so paho holds some unwritten
AFTER = 20


def until(cond, what: str, timeout: float = 60.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        got = cond()
        if got:
            return got
        time.sleep(0.05)
    raise AssertionError(f"never happened: {what}")


def test_messages_lost_in_a_broker_outage_are_counted(mqtt_broker):
    said: list[str] = []
    pub = Publisher(replace(parse_url(mqtt_broker.url("p")), queue=SENT), report=said.append)
    pub.start()
    try:
        until(lambda: pub.connected, "connected")
        os.kill(mqtt_broker.proc.pid, signal.SIGSTOP)  # frozen: reads nothing more
        for i in range(SENT):
            pub.send(f"p/event/{i % 10}", PAYLOAD, False)
        last = [-1, time.monotonic()]

        def stuck() -> bool:  # the queue no longer moves: paho holds what the socket does not take
            n = pub.q.qsize()
            if n != last[0]:
                last[:] = [n, time.monotonic()]
            return time.monotonic() - last[1] > 1.0

        until(stuck, "paho blocked on the frozen broker")
        assert 0 < pub.q.qsize() < SENT
        mqtt_broker.proc.kill()  # the broker dies with what it had not read
        mqtt_broker.proc.wait()
        mqtt_broker.proc = None
        until(lambda: not pub.connected, "the client noticing")
        mqtt_broker.start()
        sub = Subscriber(mqtt_broker, "p/event/#")
        until(lambda: pub.connects >= 2 and not pub.q.qsize(), "reconnected and the queue sent")
        for i in range(AFTER):  # the capture goes on: these reach the subscriber
            pub.send(f"p/event/{i % 10}", PAYLOAD, False)
        until(lambda: not pub.q.qsize() and len(sub.messages) >= AFTER, "the messages after the outage")
        pub.close()
        received = len(sub.messages)
        sub.close()
    finally:
        if mqtt_broker.proc is not None:
            os.kill(mqtt_broker.proc.pid, signal.SIGCONT)
    st = pub.status()
    assert pub.lost > 0 and st["lost"] == pub.lost
    summary = [s for s in said if "messages published" in s]
    assert len(summary) == 1 and f", {pub.lost} lost with the connection" in summary[0], said
    # never more counted than was lost: what the restarted broker passed on, plus what was counted lost,
    # dropped or left, is at most what was sent (messages written into the dead broker's socket are lost
    # unseen: QoS 0 has no acknowledgement)
    assert received + pub.lost + pub.dropped <= SENT + AFTER


def test_a_broker_that_accepts_and_never_answers_holds_the_end_no_longer_than_close_allows():
    with socket.socket() as s:  # listens, never reads, backlog 1: a second connect waits in the kernel
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        said: list[str] = []
        pub = Publisher(parse_url(f"mqtt://127.0.0.1:{s.getsockname()[1]}/p"), report=said.append)
        pub.start()
        pub.send("p/x", b"1", False)
        until(lambda: pub.last_error == "no answer from the broker", "the first connect given up", 30)
        t = time.monotonic()
        pub.close(timeout=1.0)
        took = time.monotonic() - t
    assert not pub._thread.is_alive()  # its last connect was bounded by what was left of the close's time
    assert took < 1.0 + 1.5  # the bound, with slack for a loaded machine (it waited 3 s: a connect of 5)
    assert said[-1].endswith("1 not delivered (no answer from the broker)")


def test_retained_values_superseded_while_the_broker_was_away_are_counted(mqtt_broker):
    """A register's value that changed while the broker was away: on the reconnect the client sends each
    retained topic's latest value, not the older ones still queued; those are counted superseded, so every
    message the capture handed over is counted once (published, dropped, lost, superseded or not delivered)."""
    said: list[str] = []
    pub = Publisher(parse_url(mqtt_broker.url("p")), report=said.append)
    pub.start()
    try:
        until(lambda: pub.connected, "connected")
        mqtt_broker.stop()  # the broker goes away
        until(lambda: not pub.connected, "the client noticing")
        for value in range(5):  # three registers change five times while the broker is away
            for reg in range(3):
                pub.send(f"p/reg/{reg}", b"%d" % (10 * reg + value), True)
        pub.send("p/event/x", b"e", False)  # an event: kept, sent after the snapshot
        assert pub.q.qsize() == 16
        mqtt_broker.start()
        until(lambda: pub.connects >= 2 and not pub.q.qsize(), "reconnected and the queue sent")
        sub = Subscriber(mqtt_broker, "p/#")
        got = sub.wait_for(lambda m: all(f"p/reg/{r}" in m for r in range(3)), what="the retained values")
        sub.close()
        published_before_close = pub.published
        pub.close()
    finally:
        if mqtt_broker.proc is None:
            mqtt_broker.start()
    assert {t: p for t, (p, _) in got.items() if t.startswith("p/reg/")} == {f"p/reg/{r}": b"%d" % (10 * r + 4)
                                                                            for r in range(3)}
    assert pub.superseded == 15 and pub.status()["superseded"] == 15
    assert pub.dropped == 0 and published_before_close >= 3 + 1  # the snapshot's three and the event
    summary = [s for s in said if "messages published" in s]
    assert len(summary) == 1 and ", 15 retained values superseded while the broker was away" in summary[0], said
