"""What `--mqtt` costs the capture: `sniffer replay` of a drive capture with and without publishing.

    .venv/bin/python benchmarks/bench_mqtt.py [--minutes 20] [--scenario a510] [--keep DIR]

1. Generate (not timed) `--minutes` of a simulated line (default: two TECO A510 drives, their real
   registers, faults and writes) with `sniffer simulate`.
2. Start a mosquitto of its own on a free local port (no persistence).
3. Replay it in a fresh process per run (`sniffer replay FILE --quiet` + flags), timed from outside
   (wall, and user+sys CPU of the sniffer process from wait4):
     peer          no --mqtt (the capture alone)
     mqtt          --mqtt mqtt://127.0.0.1:PORT/bench (every confirmed value, health, events)
     mqtt-ha       the same with --mqtt-ha --mqtt-changes (discovery, only changes)
     interval      --mqtt-interval 1s (at most one value per register a second of capture time)
     no-broker     --mqtt to a port nobody listens on (the queue fills, drops counted, the client retries)
4. Prints per run: wall s, frames/s, CPU s, and the client's last line (published, dropped).
   A replay runs as fast as it can, so the queue of the no-broker run fills at once; a live line of
   19200 baud brings at most ~100 frames/s.  Nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_pipeline as bp  # noqa: E402 - machine and revision lines


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_broker(folder: Path) -> tuple[subprocess.Popen, int]:
    exe = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
    port = free_port()
    conf = folder / "mosquitto.conf"
    conf.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n"
                    f"user {os.environ.get('USER') or 'root'}\n")
    proc = subprocess.Popen([exe, "-c", str(conf)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    for _ in range(200):
        try:
            socket.create_connection(("127.0.0.1", port), 0.2).close()
            return proc, port
        except OSError:
            time.sleep(0.05)
    raise SystemExit("mosquitto did not start (scripts/install-system-deps.sh installs it)")


def run(cap: Path, flags: list[str]) -> dict:
    argv = [sys.executable, "-m", "sniffer", "replay", str(cap), "--quiet", *flags]
    t = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    err = proc.stderr.read()
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    mqtt = [x.removeprefix("sniffer: ") for x in err.splitlines() if "mqtt:" in x]
    return {"wall": wall, "cpu": ru.ru_utime + ru.ru_stime, "mqtt": mqtt[-1] if mqtt else "",
            "rc": os.waitstatus_to_exitcode(status)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=20.0)
    ap.add_argument("--scenario", default="a510")
    ap.add_argument("--keep", metavar="DIR", help="keep the capture here")
    a = ap.parse_args()
    print(bp.machine())
    print(bp.revision())
    folder = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="bench-mqtt-"))
    folder.mkdir(parents=True, exist_ok=True)
    cap = folder / f"{a.scenario}-{a.minutes:g}min.mcap"
    if not cap.exists():
        subprocess.run([sys.executable, "-m", "sniffer", "simulate", "--scenario", a.scenario, "--duration",
                        str(a.minutes * 60), "--out", str(cap)], check=True, capture_output=True)
    out = subprocess.run([sys.executable, "-m", "sniffer", "replay", str(cap), "--format", "jsonl"],
                         capture_output=True, check=True).stdout
    frames = out.count(b"\n")
    broker, port = start_broker(folder)
    url = f"mqtt://127.0.0.1:{port}/bench"
    runs = {
        "peer": [],
        "mqtt": ["--mqtt", url],
        "mqtt-ha": ["--mqtt", url, "--mqtt-ha", "--mqtt-changes"],
        "interval": ["--mqtt", url, "--mqtt-interval", "1s"],
        "no-broker": ["--mqtt", f"mqtt://127.0.0.1:{free_port()}/bench"],
    }
    try:
        print(f"capture: {cap.name} ({cap.stat().st_size / 1e6:.1f} MB, {frames} frames)")
        print(f"{'run':<10} {'wall s':>7} {'frames/s':>9} {'CPU s':>6}  client")
        for name, flags in runs.items():
            r = run(cap, flags)
            print(f"{name:<10} {r['wall']:>7.2f} {frames / r['wall']:>9.0f} {r['cpu']:>6.2f}  "
                  f"{r['mqtt']}" + (f" (exit {r['rc']})" if r["rc"] else ""))
    finally:
        broker.terminate()
        broker.wait()
        if not a.keep:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
