import os
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))


@pytest.fixture(scope="session")
def stress_mcap(tmp_path_factory) -> str:
    """One second of the simulator's stress scenario, written once per test session (tui_helpers)."""
    from tui_helpers import write_stress_capture

    return write_stress_capture(tmp_path_factory.mktemp("stress"))


@pytest.fixture
def mqtt_broker(tmp_path):
    """A mosquitto broker of this test's own (tests/broker.py): anonymous, plain, on a free port."""
    from broker import Broker

    b = Broker(tmp_path).start()
    yield b
    b.stop()


# --- the fast lane (tests/fastlane.py): `pytest -m "not slow"` --------------------------------------
_GUARD = None


@pytest.hookimpl(tryfirst=True)  # before `-m` deselects by the marks
def pytest_collection_modifyitems(config, items):
    from fastlane import Rule, slow_reason

    rule = Rule()
    for item in items:
        if item.get_closest_marker("slow") is None and slow_reason(item, rule):
            item.add_marker(pytest.mark.slow)
        if _shares_a_fixture(item):
            item.add_marker(pytest.mark.xdist_group(item.module.__name__))
    if os.environ.get("PYTEST_XDIST_WORKER"):
        items[:] = sorted(items, key=lambda item: not _known_long(item))  # stable: the rest keep their order


# --- the suite on several cores (README: `pytest -n auto --dist loadgroup`, pytest-xdist) ----------------------
def _known_long(item) -> bool:
    """A test tests/fastlane.py lists as long (SLOW_FILES, SLOW_TESTS: minutes of simulation, worker processes).
    Under xdist these start first, and the many short tests fill in behind them: a long test taken last would
    leave the other worker idle until it ends."""
    from fastlane import SLOW_FILES, SLOW_TESTS

    name = Path(str(item.fspath)).name
    return name in SLOW_FILES or f"{name}::{getattr(item, 'originalname', None) or item.name}" in SLOW_TESTS


def _shares_a_fixture(item) -> bool:
    """Whether a test uses a fixture made once for its module (or class): a built wheel and venv, a simulated
    day, a dataset.  Such a module runs whole on one worker (`--dist loadgroup` keeps an xdist_group together),
    so the fixture is made once, not once on each worker; every other test goes to whichever worker is free.
    Session fixtures are made once per worker: they are cheap, and grouping their users would serialise the
    suite."""
    info = getattr(item, "_fixtureinfo", None)
    if info is None:
        return False
    return any(defs[-1].scope in ("module", "class", "package") for defs in info.name2fixturedefs.values())


def _compile_sources() -> None:
    """Byte-compile the project once, so that every `sniffer` process a test starts reads bytecode.

    An editable install leaves the sources uncompiled, and where PYTHONDONTWRITEBYTECODE is set (these machines,
    CI) each process would compile every module it imports again: about 0.2 s of CPU a process, hundreds of
    processes a run.  A field install (pip, pipx) compiles at install time; this does the same for the checkout.
    """
    import compileall

    root = Path(__file__).resolve().parent.parent
    for package in ("sniffer", "decoders"):
        try:
            compileall.compile_dir(str(root / package), quiet=2, workers=1)
        except OSError:  # a read-only checkout: the processes compile as they go, slower but the same
            pass


def pytest_sessionstart(session):
    global _GUARD
    _compile_sources()
    from fastlane import Guard

    _GUARD = Guard()
    _GUARD.install()


def pytest_sessionfinish(session):
    if _GUARD is not None:
        _GUARD.uninstall()


_CPU: dict[str, float] = {}  # lane test -> CPU seconds of its setup and call
_CPU_PROPERTY = "lane_cpu_s"


def _guarded(item, phase: str):
    """Run a phase of a test the lane keeps with the guard watching; fail it if it started a slow part."""
    if _GUARD is None or item.get_closest_marker("slow") is not None:
        return (yield)
    _GUARD.used.clear()
    _GUARD.watching = True
    cpu = time.process_time()
    try:
        result = yield
    finally:
        _GUARD.watching = False
        _CPU[item.nodeid] = _CPU.get(item.nodeid, 0.0) + time.process_time() - cpu
        if phase == "call":  # on the test's report, for the summary in pytest-xdist's controller
            item.user_properties.append((_CPU_PROPERTY, _CPU[item.nodeid]))
    if _GUARD.used:
        pytest.fail(f"{item.nodeid} {' and '.join(_GUARD.used)} in its {phase} but is not marked slow: the fast "
                    f"lane (-m 'not slow') keeps no processes, ptys, Pilot, browsers or brokers.  Let the rule in "
                    f"tests/fastlane.py see it (SLOW_NAMES, SLOW_FILES, SLOW_TESTS) or mark it "
                    f"@pytest.mark.slow.", pytrace=False)
    return result


@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item):
    return (yield from _guarded(item, "setup"))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item):
    return (yield from _guarded(item, "call"))


def pytest_runtest_logreport(report):
    """A lane test's CPU as its worker measured it (under xdist the summary is written by the controller)."""
    for name, value in report.user_properties:
        if name == _CPU_PROPERTY:
            _CPU[report.nodeid] = value


def pytest_terminal_summary(terminalreporter):
    """Name the lane's tests that took more CPU than fastlane.CPU_NOTE_S: candidates for SLOW_TESTS."""
    from fastlane import CPU_NOTE_S

    heavy = sorted(((s, n) for n, s in _CPU.items() if s > CPU_NOTE_S), reverse=True)
    if heavy:
        terminalreporter.section("fast lane: tests over %.0f s of CPU (tests/fastlane.py SLOW_TESTS?)" % CPU_NOTE_S)
        for s, n in heavy[:20]:
            terminalreporter.write_line(f"{s:6.1f} s  {n}")
