"""The fuzz targets (fuzz/targets.py): every input of the corpus replayed, and a short coverage-guided run.

The corpus (fuzz/corpus/TARGET/) holds each target's seeds and every input a fuzzer found that once
crashed a reader (kept after the fix, so it stays fixed): each is run through its target here, in the
fast lane, with no fuzzer.  The slow lane runs atheris on every target at once (`fuzz/run.py all`) for
a few seconds: any exception but the project's one-line errors, an exit code a command does not give, a
byte a framer loses, or a case past its time is a crash.  docs/fuzzing.md: the longer run.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "fuzz"))

from targets import CORPUS, FILE_TARGETS, TARGETS, one  # noqa: E402

RUN_S = 15  # the suite's run: seconds of fuzzing, every target in one process (their startup once)


def _names(names):
    """The targets, the sigrok one marked slow (sigrok-cli decodes a .sr file: a process)."""
    return [pytest.param(n, marks=pytest.mark.slow) if n == "sigrok" else n for n in sorted(names)]


@pytest.mark.parametrize("name", _names(TARGETS))
def test_every_corpus_input_runs_through_its_target(name):
    inputs = sorted((CORPUS / name).iterdir())
    assert any(p.name.startswith("seed-") for p in inputs), f"fuzz/corpus/{name}: no seed (python fuzz/seeds.py)"
    for path in inputs:
        one(name, path.read_bytes())  # a bug raises; a file target's exit code is checked inside


@pytest.mark.parametrize("name", _names(FILE_TARGETS))
def test_every_file_target_reads_its_first_seed_cleanly(name):
    """A seed the command refuses would only fuzz the refusal: each target's first seed is read (exit 0)."""
    first = sorted((CORPUS / name).glob("seed-*"))[0]
    assert one(name, first.read_bytes()) == 0, first


def test_a_short_coverage_guided_run_of_every_target_finds_nothing(tmp_path):
    pytest.importorskip("atheris", reason="atheris is in the test extra (Linux x86-64 wheels)")
    r = subprocess.run([sys.executable, str(ROOT / "fuzz" / "run.py"), "all", f"-max_total_time={RUN_S}",
                        "-timeout=60", "-rss_limit_mb=4096", f"-artifact_prefix={tmp_path}/"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=RUN_S + 240)
    crashes = sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(("crash-", "timeout-", "oom-")))
    tail = "\n".join(line for line in r.stderr.splitlines() if not line.startswith("INFO: Instrumenting"))[-3000:]
    assert r.returncode == 0 and not crashes, (r.returncode, crashes, tail)
    done = [line for line in r.stderr.splitlines() if line.startswith("Done ")]
    assert done and int(done[-1].split()[1]) > 0, tail  # "Done N runs in S second(s)": it ran
