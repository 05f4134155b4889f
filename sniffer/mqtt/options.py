"""The MQTT flags of a capture (`--mqtt URL`, `--mqtt-ca` ... `--mqtt-ha`), checked once: MqttSpec.

    mqtt://[USER[:PASSWORD]@]HOST[:PORT]/PREFIX      plain (port 1883)
    mqtts://[USER[:PASSWORD]@]HOST[:PORT]/PREFIX     TLS (port 8883): the system's CAs, or --mqtt-ca

A user without a password in the URL takes it from $SNIFFER_MQTT_PASSWORD (it then stays out of the
process list).  --mqtt-cert/--mqtt-key give a client certificate.  Everything that cannot work is one
SettingsError line before the capture starts (a bad URL, a TLS file that is missing or not a
certificate / key); a broker that cannot be reached is not: the capture starts and the client retries.
"""

from __future__ import annotations

import os
import re
import ssl
from dataclasses import dataclass
from urllib.parse import unquote, urlsplit

from sniffer import need
from sniffer.inputs.address import is_host
from sniffer.line import SettingsError

DEFAULT_QUEUE = 10_000
DEFAULT_HA_PREFIX = "homeassistant"
PASSWORD_ENV = "SNIFFER_MQTT_PASSWORD"
_PREFIX_OK = re.compile(r"[^#+\x00]+\Z")


@dataclass(frozen=True)
class MqttSpec:
    url: str  # as given
    host: str
    port: int
    prefix: str  # topic prefix: no leading/trailing '/', no wildcards
    tls: bool = False
    username: str | None = None
    password: str | None = None
    ca: str | None = None
    cert: str | None = None
    key: str | None = None
    interval_s: float = 0.0  # at most one value per topic in this much capture time (the latest is kept)
    changes: bool = False  # publish a value only when it differs from the last one published
    ha_prefix: str | None = None  # Home Assistant discovery prefix (None: no discovery)
    queue: int = DEFAULT_QUEUE  # messages waiting for the broker; past that they are dropped (counted)

    @property
    def broker(self) -> str:
        """host:port, for messages (never the password)."""
        return f"{'[' + self.host + ']' if ':' in self.host else self.host}:{self.port}"

    @classmethod
    def from_args(cls, args) -> MqttSpec | None:
        """The spec of the parsed flags, None without --mqtt; SettingsError for what cannot work."""
        def opt(name, default=None):
            return getattr(args, name, default)

        url = opt("mqtt")
        if not url:
            for flag in ("ca", "cert", "key", "interval", "changes", "ha", "ha_prefix", "queue"):
                if opt(f"mqtt_{flag}") not in (None, False):
                    raise SettingsError(f"--mqtt-{flag.replace('_', '-')} needs --mqtt URL (the broker to publish to)")
            return None
        need("mqtt", "--mqtt")
        spec = parse_url(url)
        interval = opt("mqtt_interval")
        if interval is not None:
            from sniffer.triggers.options import seconds

            spec = _with(spec, interval_s=seconds(interval, "--mqtt-interval"))
        queue = opt("mqtt_queue")
        if queue is not None:
            spec = _with(spec, queue=queue)
        ha = (opt("mqtt_ha_prefix") or DEFAULT_HA_PREFIX) if opt("mqtt_ha") else None
        if opt("mqtt_ha_prefix") and not ha:
            raise SettingsError("--mqtt-ha-prefix needs --mqtt-ha (Home Assistant discovery)")
        if ha:
            if not _PREFIX_OK.match(ha) or ha.startswith("/") or ha.endswith("/"):
                raise SettingsError(f"--mqtt-ha-prefix {ha[:60]!r}: a discovery prefix without '#', '+' or a "
                                    "leading or trailing '/' (default homeassistant)")
        spec = _with(spec, changes=bool(opt("mqtt_changes")), ha_prefix=ha or None,
                     ca=opt("mqtt_ca"), cert=opt("mqtt_cert"), key=opt("mqtt_key"))
        spec.tls_context()  # bad TLS files: one line now, not a retry loop later
        return spec

    def tls_context(self) -> ssl.SSLContext | None:
        """The TLS context of an mqtts:// URL (None for mqtt://); SettingsError for unusable files."""
        if not self.tls:
            for flag, path in (("--mqtt-ca", self.ca), ("--mqtt-cert", self.cert), ("--mqtt-key", self.key)):
                if path:
                    raise SettingsError(f"{flag} needs an mqtts:// URL (TLS); {_safe(self.url)} is plain MQTT")
            return None
        if self.key and not self.cert:
            raise SettingsError("--mqtt-key needs --mqtt-cert (the client certificate it belongs to)")
        for flag, path in (("--mqtt-ca", self.ca), ("--mqtt-cert", self.cert), ("--mqtt-key", self.key)):
            if path and not os.path.isfile(path):
                raise SettingsError(f"{flag} {path}: no such file")
        ctx = ssl.create_default_context()
        try:
            if self.ca:
                ctx.load_verify_locations(cafile=self.ca)
        except (ssl.SSLError, OSError, ValueError) as e:
            raise SettingsError(f"--mqtt-ca {self.ca}: not a CA certificate (PEM): {_reason(e)}") from None
        try:
            if self.cert:
                ctx.load_cert_chain(self.cert, self.key)
        except (ssl.SSLError, OSError, ValueError) as e:
            what = f"--mqtt-cert {self.cert}" + (f" / --mqtt-key {self.key}" if self.key else "")
            raise SettingsError(f"{what}: not a certificate and its private key (PEM): {_reason(e)}") from None
        return ctx


def parse_url(url: str) -> MqttSpec:
    """MqttSpec of mqtt[s]://[user[:pass]@]host[:port]/prefix; SettingsError naming what is wrong."""
    shown = _safe(url)
    if "#" in url or "?" in url:
        raise SettingsError(f"--mqtt {shown}: the topic prefix may not hold '#', '+' or '?' (in a password "
                            "write them %23, %2B, %3F)")
    try:
        u = urlsplit(url)
        port = u.port
    except ValueError as e:
        raise SettingsError(f"--mqtt {shown}: {e}") from None
    if u.scheme not in ("mqtt", "mqtts"):
        raise SettingsError(f"--mqtt {shown}: give mqtt://HOST[:PORT]/PREFIX (or mqtts:// for TLS)")
    if not u.hostname:
        raise SettingsError(f"--mqtt {shown}: no broker host (mqtt://HOST[:PORT]/PREFIX)")
    if not is_host(u.hostname):
        raise SettingsError(f"--mqtt {shown}: {u.hostname[:40]!r} is not a host name or address "
                            "(mqtt://HOST[:PORT]/PREFIX)")
    if port == 0:
        raise SettingsError(f"--mqtt {shown}: port 0")
    prefix = unquote(u.path).strip("/")
    if not prefix:
        raise SettingsError(f"--mqtt {shown}: no topic prefix (mqtt://{u.hostname}/PREFIX, e.g. /plant/line3)")
    if not _PREFIX_OK.match(prefix) or "//" in prefix:
        raise SettingsError(f"--mqtt {shown}: the topic prefix {prefix!r} may not hold '#', '+' or an empty level")
    tls = u.scheme == "mqtts"
    user = unquote(u.username) if u.username else None
    password = unquote(u.password) if u.password is not None else None
    if user and password is None:
        password = os.environ.get(PASSWORD_ENV)
    return MqttSpec(url, u.hostname, port or (8883 if tls else 1883), prefix, tls, user, password)


def _with(spec: MqttSpec, **kw) -> MqttSpec:
    from dataclasses import replace

    return replace(spec, **kw)


def _safe(url: str) -> str:
    """The URL with its password hidden (error lines, the status)."""
    return re.sub(r"(://[^:/@]*:)[^@/]*@", r"\1***@", str(url))[:200]


def _reason(e: Exception) -> str:
    return getattr(e, "reason", None) or getattr(e, "strerror", None) or str(e) or type(e).__name__


__all__ = ["DEFAULT_QUEUE", "MqttSpec", "PASSWORD_ENV", "parse_url"]
