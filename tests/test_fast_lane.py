"""The fast lane keeps honest: the rule of tests/fastlane.py sees what makes a test slow, through the helpers
it calls, the lists name tests that exist, and the guard notices a process started where none should be."""

from __future__ import annotations

import ast
import os
import re
import subprocess
from pathlib import Path

import pytest
from fastlane import SLOW_FILES, SLOW_TESTS, Guard, Rule

from sniffer.cli import main

TESTS = Path(__file__).resolve().parent


# the kinds of code the rule must call slow, written as tests write them
async def _pilot():
    app = object()
    async with app.run_test() as pilot:  # noqa: F841 - never run: the rule reads the code
        pass


def _process():
    return subprocess.run(["true"])


def _helper_that_starts_a_pty():
    return os.openpty()


def _calls_a_helper():
    return _helper_that_starts_a_pty()


def _runs_a_capture_command():
    return main(["live", "/dev/ttyUSB0", "--headless"])


def _fast():
    return sum(range(10)) + len(re.findall("a", "banana"))


@pytest.mark.parametrize("func, says", [
    (_pilot, "run_test"), (_process, "subprocess"), (_helper_that_starts_a_pty, "openpty"),
    (_calls_a_helper, "openpty"), (_runs_a_capture_command, "sniffer live"),
])
def test_the_rule_sees_processes_ptys_and_pilot_through_helpers(func, says):
    why = Rule().why(func)
    assert why and says in why


def test_the_rule_leaves_plain_code_in_the_lane():
    assert Rule().why(_fast) is None


def test_every_listed_file_and_test_exists():
    """A renamed test must not leave a stale entry (and its test back in the lane)."""
    for name in SLOW_FILES:
        assert (TESTS / name).is_file(), name
    for entry in SLOW_TESTS:
        file, _, test = entry.partition("::")
        tree = ast.parse((TESTS / file).read_text(encoding="utf-8"))
        names = {n.name for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}
        assert test in names, entry


def test_the_slow_marker_is_registered_and_described():
    text = (TESTS.parent / "pyproject.toml").read_text(encoding="utf-8")
    assert '"slow: ' in text and "processes, ptys, Pilot" in text


def test_the_guard_notices_only_while_it_watches():
    before = subprocess.Popen.__init__, os.openpty
    guard = Guard()
    guard.install()
    try:
        os.close(os.dup(0))  # not a thing it watches
        fd_a, fd_b = os.openpty()  # not watching yet
        os.close(fd_a), os.close(fd_b)
        assert guard.used == []
        guard.watching = True
        subprocess.run(["true"], check=True)
        fd_a, fd_b = os.openpty()
        os.close(fd_a), os.close(fd_b)
        guard.watching = False
        assert guard.used == ["started a process (subprocess.Popen)", "opened a pseudo-terminal (os.openpty)"]
    finally:
        guard.uninstall()
    assert (subprocess.Popen.__init__, os.openpty) == before  # put back as it found them
