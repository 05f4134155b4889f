"""A real mosquitto broker for the MQTT tests: a free local port, a generated config, users and TLS on demand.

    b = Broker(tmp_path, users={"plc": "s3cret"}, tls=True).start()
    ... b.url("plant") ...; b.stop(); b.start()   # the same port again (a broker that went away)

A test that needs mosquitto and cannot start it fails with the reason (never skips): the suite's
system-deps script installs it (scripts/install-system-deps.sh).  `Subscriber` is a real client that
keeps every message (topic, payload, retain flag) it gets.
"""

from __future__ import annotations

import getpass
import json
import os
import shutil
import socket
import subprocess
import threading
import time
from pathlib import Path

import pytest

START_S = 15.0


def mosquitto() -> str:
    exe = shutil.which("mosquitto") or next((p for p in ("/usr/sbin/mosquitto",) if os.access(p, os.X_OK)), None)
    if exe is None:
        pytest.fail("mosquitto is not installed: run scripts/install-system-deps.sh "
                    "(the MQTT tests need a real broker)")
    return exe


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def openssl(*args: str, cwd: Path) -> None:
    exe = shutil.which("openssl")
    if exe is None:
        pytest.fail("openssl is not installed: run scripts/install-system-deps.sh (the TLS broker's certificates)")
    r = subprocess.run([exe, *args], cwd=cwd, capture_output=True, text=True)
    if r.returncode:
        pytest.fail(f"openssl {' '.join(args[:2])}: {r.stderr.strip()[-400:]}")


def make_ca(folder: Path, name: str = "ca") -> Path:
    """A CA key and self-signed certificate (name.key, name.pem) made now."""
    folder.mkdir(parents=True, exist_ok=True)
    openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj", f"/CN=sniffer test {name}",
            "-keyout", f"{name}.key", "-out", f"{name}.pem", cwd=folder)
    return folder / f"{name}.pem"


def make_server_cert(folder: Path, ca: str = "ca", name: str = "server") -> tuple[Path, Path]:
    """NAME.pem / NAME.key for 127.0.0.1 and localhost, signed by the CA `ca` in folder (a server's, or
    a client's certificate)."""
    (folder / "san.ext").write_text("subjectAltName=IP:127.0.0.1,DNS:localhost\n")
    openssl("req", "-newkey", "rsa:2048", "-nodes", "-subj", f"/CN={name}", "-keyout", f"{name}.key",
            "-out", f"{name}.csr", cwd=folder)
    openssl("x509", "-req", "-in", f"{name}.csr", "-CA", f"{ca}.pem", "-CAkey", f"{ca}.key", "-CAcreateserial",
            "-days", "2", "-extfile", "san.ext", "-out", f"{name}.pem", cwd=folder)
    return folder / f"{name}.pem", folder / f"{name}.key"


class Broker:
    def __init__(self, folder: Path, *, users: dict[str, str] | None = None, tls: bool = False,
                 client_certs: bool = False) -> None:
        self.folder = Path(folder) / f"broker-{free_port()}"
        self.folder.mkdir(parents=True)
        self.users = users
        self.tls = tls
        self.port = free_port()
        self.proc: subprocess.Popen | None = None
        self.ca: Path | None = None
        self.client_cert = self.client_key = None  # with client_certs: one the CA signed
        lines = [f"listener {self.port} 127.0.0.1", "persistence false", f"user {getpass.getuser()}",
                 "log_dest stderr", "log_type error", "log_type warning"]
        if users:
            pw = self.folder / "passwd"
            pw.write_text("")
            for u, p in users.items():
                exe = shutil.which("mosquitto_passwd") or "/usr/bin/mosquitto_passwd"
                r = subprocess.run([exe, "-b", str(pw), u, p], capture_output=True, text=True)
                if r.returncode:
                    pytest.fail(f"mosquitto_passwd: {r.stderr.strip()}")
            os.chmod(pw, 0o600)
            lines += ["allow_anonymous false", f"password_file {pw}"]
        else:
            lines.append("allow_anonymous true")
        if tls:
            self.ca = make_ca(self.folder)
            cert, key = make_server_cert(self.folder)
            lines += [f"cafile {self.ca}", f"certfile {cert}", f"keyfile {key}"]
            if client_certs:  # a client must show a certificate the CA signed
                lines.append("require_certificate true")
                self.client_cert, self.client_key = make_server_cert(self.folder, name="client")
        self.conf = self.folder / "mosquitto.conf"
        self.conf.write_text("\n".join(lines) + "\n")

    @property
    def scheme(self) -> str:
        return "mqtts" if self.tls else "mqtt"

    def url(self, prefix: str = "plant/line3", user: str | None = None, password: str | None = None) -> str:
        auth = f"{user}{'' if password is None else ':' + password}@" if user else ""
        return f"{self.scheme}://{auth}127.0.0.1:{self.port}/{prefix}"

    def start(self) -> Broker:
        self.log = open(self.folder / "mosquitto.log", "ab")
        self.proc = subprocess.Popen([mosquitto(), "-c", str(self.conf)], stdout=self.log, stderr=self.log)
        deadline = time.monotonic() + START_S
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                pytest.fail(f"mosquitto did not start (exit {self.proc.returncode}): "
                            f"{(self.folder / 'mosquitto.log').read_text()[-600:]}")
            try:
                socket.create_connection(("127.0.0.1", self.port), 0.2).close()
                return self
            except OSError:
                time.sleep(0.05)
        self.stop()
        pytest.fail(f"mosquitto did not listen on port {self.port} within {START_S:.0f} s")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.proc = None


class Subscriber:
    """A real MQTT client subscribed to `topic`, keeping every message: [(topic, payload bytes, retain)]."""

    def __init__(self, broker: Broker, topic: str = "#", *, user: str | None = None, password: str | None = None):
        import paho.mqtt.client as mqtt

        self.messages: list[tuple[str, bytes, bool]] = []
        self._lock = threading.Lock()
        self.subscribed = threading.Event()
        c = self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=f"test-sub-{os.urandom(3).hex()}")
        if user:
            c.username_pw_set(user, password)
        if broker.tls:
            c.tls_set(ca_certs=str(broker.ca), certfile=str(broker.client_cert) if broker.client_cert else None,
                      keyfile=str(broker.client_key) if broker.client_cert else None)
        c.on_message = self._on_message
        c.on_subscribe = lambda *a: self.subscribed.set()
        c.connect("127.0.0.1", broker.port)
        c.subscribe(topic)
        c.loop_start()
        if not self.subscribed.wait(10):
            pytest.fail("the test's subscriber got no SUBACK")

    def _on_message(self, client, userdata, msg) -> None:
        with self._lock:
            self.messages.append((msg.topic, bytes(msg.payload), bool(msg.retain)))

    def latest(self) -> dict[str, tuple[bytes, bool]]:
        with self._lock:
            return {t: (p, r) for t, p, r in self.messages}

    def json(self, topic: str) -> dict:
        return json.loads(self.latest()[topic][0])

    def wait_for(self, pred, timeout: float = 30.0, what: str = "messages") -> dict:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            got = self.latest()
            if pred(got):
                return got
            time.sleep(0.05)
        pytest.fail(f"no {what} within {timeout:.0f} s; got {sorted(self.latest())[:20]}")

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


def retained(broker: Broker, topic: str = "#", settle_s: float = 1.0, *, live: bool = False,
             **kw) -> dict[str, bytes]:
    """The broker's retained messages under `topic` (a fresh subscriber gets them first, flagged retained);
    `live`: also those that come while it listens (retained ones published meanwhile come unflagged)."""
    sub = Subscriber(broker, topic, **kw)
    try:
        last, n = time.monotonic(), -1
        while time.monotonic() - last < settle_s:  # until nothing new came for settle_s
            time.sleep(0.05)
            k = len(sub.messages)
            if k != n:
                n, last = k, time.monotonic()
        return {t: p for t, p, r in sub.messages if r or live}
    finally:
        sub.close()
