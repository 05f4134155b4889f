"""`sniffer extcap --install`: a launcher in the user's personal extcap folder, so Wireshark and tshark list the
sniffer's interfaces.

The folder is the one `tshark -G folders` names "Personal Extcap path" (Wireshark 4.2 and later), else the
"extcap" folder of its "Personal configuration" (Wireshark 3.x and 4.0 look there).  The launcher runs this
Python (`sys.executable -m sniffer extcap`) with the ports and bus files given at install, which are then
listed as interfaces too (a port without a /dev/serial/by-id name, a gateway URL, a plant's bus file).
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys

from sniffer.events import CaptureError as InstallError  # one line, exit 2 (sniffer.cli)

NAME = "rs485-sniffer"


def personal_folder() -> str:
    """The personal extcap folder, from `tshark -G folders`; UsageError without tshark."""
    exe = shutil.which("tshark")
    if exe is None:
        raise InstallError("extcap --install: tshark not found (install Wireshark's tshark; it names the personal "
                         "extcap folder), or copy the launcher by hand: docs/wireshark.md")
    try:
        r = subprocess.run([exe, "-G", "folders"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as e:
        raise InstallError(f"extcap --install: `tshark -G folders` failed: {e}") from None
    folders = {}
    for line in r.stdout.splitlines():
        key, sep, value = line.partition(":")
        if sep:
            folders.setdefault(key.strip().lower(), value.strip())
    if folders.get("personal extcap path"):
        return folders["personal extcap path"]
    if folders.get("personal configuration"):
        return os.path.join(folders["personal configuration"], "extcap")
    raise InstallError("extcap --install: `tshark -G folders` names no personal folder")


def launcher_text(ports=(), bus_files=()) -> str:
    extra = [a for p in ports for a in ("--list-port", p)]
    extra += [a for b in bus_files for a in ("--list-bus", os.path.abspath(b))]
    if os.name == "nt":
        args = " ".join(f'"{a}"' for a in [sys.executable, "-m", "sniffer", "extcap", *extra])
        return f"@echo off\r\n{args} %*\r\n"
    args = " ".join(shlex.quote(a) for a in [sys.executable, "-m", "sniffer", "extcap", *extra])
    return ("#!/bin/sh\n# written by `sniffer extcap --install`: Wireshark runs it to list and capture RS-485 lines\n"
            f"exec {args} \"$@\"\n")


def install(folder: str | None = None, ports=(), bus_files=()) -> str:
    """Write the launcher (atomically) into `folder` (default: the personal extcap folder); its path."""
    folder = folder or personal_folder()
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, NAME + (".bat" if os.name == "nt" else ""))
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8", newline="") as f:
        f.write(launcher_text(ports, bus_files))
    os.chmod(tmp, 0o755)
    os.replace(tmp, path)
    return path
