"""What the sniffer writes cannot harm what is there: `--status` and every output flag under the output rules
(never an input, never anything but a regular file), files and folders at most 0644 / 0755 whatever the
umask, and a full disk (a real file-size limit, RLIMIT_FSIZE: the OS refuses the write) leaves under the
name asked for only complete files, what was cut short as NAME.part.  Every command runs as a process."""

from __future__ import annotations

import os
import resource
import signal
import stat
import subprocess
import sys

import pytest
from mcap.reader import make_reader

SNIFFER = [sys.executable, "-m", "sniffer"]
BUS = '[serial]\nbaud = 19200\nparity = "E"\nstopbits = 1\n'
MAP_CSV = "address,name,type\n0,Speed,u16\n"


def run(*args, cwd=None, preexec_fn=None, timeout=300, env=None):
    return subprocess.run(SNIFFER + [str(a) for a in args], capture_output=True, text=True, timeout=timeout,
                          cwd=cwd, preexec_fn=preexec_fn, env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1",
                                                               **(env or {})})


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    """60 s of the `errors` scenario (CRC errors for the triggers), about 800 kB of MCAP."""
    path = tmp_path_factory.mktemp("cap") / "errors.mcap"
    r = run("simulate", "--scenario", "errors", "--duration", "60", "--seed", "2", "--out", path)
    assert r.returncode == 0, r.stderr
    return path


def _one_error(r, says: str) -> None:
    lines = [x for x in r.stderr.splitlines() if x.strip()]
    assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("sniffer: error:"), r.stderr
    assert says in lines[0] and "Traceback" not in r.stderr


def _snapshot(path) -> tuple:
    st = os.lstat(path)
    return stat.S_IFMT(st.st_mode), st.st_ino, (path.read_bytes() if stat.S_ISREG(st.st_mode) else b"")


# ---------------------------------------------------------------- --status under the output rules
@pytest.mark.parametrize("case", ["input", "fifo", "link to a fifo", "folder", "bus file", "model file", "out",
                                  "index of an input"])
def test_status_never_replaces_an_input_or_what_is_not_a_regular_file(capture, tmp_path, case):
    cap = tmp_path / "in.mcap"
    cap.write_bytes(capture.read_bytes())
    bus, model = tmp_path / "line.toml", tmp_path / "m.csv"
    bus.write_text(BUS)
    model.write_text(MAP_CSV)
    argv, target, says = ["replay", cap, "--quiet"], None, "is also an input"
    if case == "input":
        target = cap
    elif case in ("fifo", "link to a fifo"):
        os.mkfifo(tmp_path / "fifo")
        target, says = tmp_path / "fifo", "not a regular file"
        if case == "link to a fifo":
            (tmp_path / "link").symlink_to(tmp_path / "fifo")
            target = tmp_path / "link"
    elif case == "folder":
        target, says = tmp_path, "is a folder"
    elif case == "bus file":
        argv += ["--bus", bus]
        target = bus
    elif case == "model file":
        argv += ["--model-file", model]
        target = model
    elif case == "out":  # a capture written and its status: two outputs, one name
        out = tmp_path / "sim.mcap"
        out.write_bytes(b"kept")
        argv, target, says = ["simulate", "--duration", "2", "--out", out], out, "another output"
    else:  # a rotated capture's folder is the input: its index is read
        r = run("replay", cap, "--quiet", "--rotate", "1h", "--out", tmp_path / "segs")
        assert r.returncode == 0, r.stderr
        argv, target = ["replay", tmp_path / "segs", "--quiet"], tmp_path / "segs" / "index.json"
    before = _snapshot(target)
    r = run(*argv, "--status", target)
    _one_error(r, says)
    assert "--status" in r.stderr
    assert _snapshot(target) == before
    assert not [p for p in tmp_path.iterdir() if ".tmp" in p.name or p.name.endswith(".part")]


# ---------------------------------------------------------------- every output: never an input
@pytest.mark.parametrize("command", ["learn", "export", "report", "check", "export-model"])
def test_no_output_is_any_file_the_command_reads(capture, tmp_path, command):
    """The bus file and the model files are inputs of every command that decodes, as the capture is."""
    bus, model = tmp_path / "line.toml", tmp_path / "m.csv"
    bus.write_text(BUS)
    model.write_text(MAP_CSV)
    argv, target = {
        "learn": (["learn", capture, "--bus", bus, "--out", bus], bus),
        "export": (["export", capture, "--bus", bus, "--to", "jsonl", "--out", bus], bus),
        "report": (["report", capture, "--bus", bus, "--out", bus], bus),
        "check": (["check", capture, "--bus", bus, "--golden", bus, "--update-golden"], bus),
        "export-model": (["export", capture, "--model-file", model, "--to", "csv", "--out", model], model),
    }[command]
    before = _snapshot(target)
    r = run(*argv)
    assert r.returncode == 2 and "is also an input" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert _snapshot(target) == before


# ---------------------------------------------------------------- modes: never more than 0644 / 0755
def _umask_000():
    os.umask(0)


def test_files_and_folders_are_not_writable_by_others_under_umask_000(capture, tmp_path):
    out = tmp_path / "out"
    out.mkdir(mode=0o755)
    cmds = [
        ["simulate", "--duration", "5", "--out", "sim.mcap", "--status", "sim.status.json"],
        ["simulate", "--duration", "5", "--out", "sim.csv"],
        ["replay", capture, "--quiet", "--rotate", "1MB", "--out", "segs", "--trigger", "crc", "--pre", "2s",
         "--post", "1s", "--windows", "windows"],
        *(["export", capture, "--to", fmt, "--out", f"x.{fmt}"] for fmt in ("csv", "parquet", "pcap", "pcapng",
                                                                           "jsonl", "mcap")),
        ["export", capture, "--to", "dataset", "fleet"],
        ["report", capture, "--out", "r.html"],
        ["learn", capture, "--out", "learned.toml"],
        ["check", capture, "--golden", "g.txt", "--update-golden"],
        ["repair", capture, "--out", "repaired.mcap"],
    ]
    for argv in cmds:
        r = run(*argv, cwd=out, preexec_fn=_umask_000)
        assert r.returncode in (0, 1), (argv, r.stderr)  # check --update-golden says 1: a new golden file
    made = []
    for root, dirs, files in os.walk(out):
        made += [os.path.join(root, n) for n in dirs + files]
    assert len(made) > 30
    loose = {p: oct(os.stat(p).st_mode & 0o777) for p in made if os.stat(p).st_mode & 0o022}
    assert not loose


def test_no_file_holds_the_mqtt_password(capture, tmp_path):
    """Nothing the sniffer writes needs mode 0600: the password is in none of its files."""
    secret = "pw-4f1b7c9e"
    r = run("replay", capture, "--quiet", "--rotate", "1h", "--out", tmp_path / "segs", "--trigger", "crc",
            "--pre", "2s", "--post", "1s", "--windows", tmp_path / "w",
            "--mqtt", f"mqtt://ops:{secret}@127.0.0.1:1/plant", timeout=120)
    assert r.returncode in (0, 1), r.stderr
    assert secret not in r.stderr
    files = [os.path.join(root, n) for root, _, names in os.walk(tmp_path) for n in names]
    assert len(files) > 3
    assert not [p for p in files if secret.encode() in open(p, "rb").read()]


# ---------------------------------------------------------------- a full disk
def _file_limit(limit: int):
    def pre():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # the write fails (EFBIG) instead of killing
    return pre


def _readable_mcaps(folder) -> list:
    """Every file under an .mcap name in `folder`, read to its end by the mcap library (index and all)."""
    names = sorted(p for p in folder.rglob("*.mcap"))
    for p in names:
        with open(p, "rb") as fh:
            reader = make_reader(fh)
            assert sum(1 for _ in reader.iter_messages()) > 0
            assert reader.get_summary() is not None
    return names


@pytest.mark.parametrize("name", ["cut.mcap", "cut.csv"])
def test_a_capture_cut_short_stays_a_part_file(tmp_path, name):
    r = run("simulate", "--duration", "120", "--out", name, cwd=tmp_path, preexec_fn=_file_limit(600_000))
    assert r.returncode == 1, r.stderr
    part = tmp_path / f"{name}.part"
    assert not (tmp_path / name).exists() and part.is_file() and part.stat().st_size > 1000
    assert f"kept as {name}.part" in r.stderr and "Traceback" not in r.stderr
    if name.endswith(".mcap"):
        r = run("replay", tmp_path / name, "--format", "jsonl")  # read from the part file, and said so
        assert r.returncode == 0 and r.stdout.count("\n") > 100 and "not closed cleanly" in r.stderr


@pytest.mark.parametrize("fmt", ["csv", "parquet", "pcap", "pcapng", "jsonl", "mcap"])
def test_an_export_that_does_not_fit_leaves_nothing(capture, tmp_path, fmt):
    r = run("export", capture, "--to", fmt, "--out", f"x.{fmt}", cwd=tmp_path, preexec_fn=_file_limit(100_000))
    assert r.returncode == 1 and "cannot write" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert os.listdir(tmp_path) == []


def test_a_segment_cut_short_stays_a_part_file_and_the_index_says_so(capture, tmp_path):
    import json

    r = run("replay", capture, "--quiet", "--rotate", "10MB", "--out", "segs", cwd=tmp_path,
            preexec_fn=_file_limit(250_000))
    assert r.returncode == 1 and "kept as segs/" in r.stderr, r.stderr
    assert _readable_mcaps(tmp_path) == []
    (part,) = (tmp_path / "segs").glob("*.mcap.part")
    (seg,) = json.loads((tmp_path / "segs" / "index.json").read_text())["segments"]
    assert seg["state"] == "killed" and seg["extra"]["part"] == part.name and seg["bytes"] == part.stat().st_size
    r = run("replay", tmp_path / "segs", "--format", "jsonl")
    assert r.stdout.count("\n") > 100


def test_trigger_windows_that_do_not_fit_stay_part_files(capture, tmp_path):
    from sniffer.triggers import read_trigger

    r = run("replay", capture, "--quiet", "--trigger", "crc", "--pre", "20s", "--post", "10s",
            "--max-window", "20s", "--windows", tmp_path, preexec_fn=_file_limit(60_000))
    assert r.returncode == 0, r.stderr
    parts = sorted(tmp_path.glob("*.trigger-*.mcap.part"))
    assert parts and all(p.stat().st_size > 1000 for p in parts)
    kept = [x for x in r.stderr.splitlines() if "not written" in x and "kept as" in x]
    assert len(kept) == len(parts)
    for w in _readable_mcaps(tmp_path):  # what carries a window's name is a whole window
        assert read_trigger(str(w))["rules"] == ["crc"]
