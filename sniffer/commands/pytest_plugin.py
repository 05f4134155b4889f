"""pytest plugin: check your own captures against reviewed golden decodes.

Installed with the package (entry point `pytest11: sniffer`).  In a test:

    def test_line3(sniffer_check):
        sniffer_check("captures/line3.mcap", "golden/line3.txt")

    @pytest.mark.sniffer_golden("captures/line3.csv", "golden/line3.txt", baud=19200, parity="E")
    def test_line3_marker():
        pass  # the marker runs the check before the test body

Relative paths count from the test file's folder.  A difference fails the
test with a unified diff; `pytest --update-golden` rewrites the goldens
(then review them with git diff).  Timing tolerances: keyword arguments
`time_tol_ms` / `latency_tol_ms`, or `--sniffer-time-tol-ms` /
`--sniffer-latency-tol-ms` for the whole run.
"""

from __future__ import annotations

from pathlib import Path

import pytest


def pytest_addoption(parser):
    g = parser.getgroup("sniffer", "RS-485 sniffer golden captures")
    g.addoption("--update-golden", action="store_true", default=False,
                help="rewrite the golden decodes checked by sniffer_check (review the diff!)")
    g.addoption("--sniffer-time-tol-ms", type=float, default=None,
                help="frame time tolerance for sniffer_check (default 1 ms)")
    g.addoption("--sniffer-latency-tol-ms", type=float, default=None,
                help="response latency tolerance for sniffer_check (default 1 ms)")


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "sniffer_golden(capture, golden, **options): check CAPTURE's decode against GOLDEN "
        "before the test body",
    )


class SnifferChecker:
    def __init__(self, base: Path, update: bool, time_tol: float | None, lat_tol: float | None) -> None:
        self.base = base
        self.update = update
        self.time_tol = time_tol
        self.lat_tol = lat_tol

    def __call__(self, capture, golden, *, baud=None, parity=None, stopbits=None, devices=None,
                 protocol=None, timeout_ms=None, model_files=None, time_tol_ms=None,
                 latency_tol_ms=None) -> str:
        """Check; returns the golden text path's message on update. Fails the test on a difference."""
        from sniffer.analysis.check import EXIT_DIFFERENT, EXIT_SAME, Tolerances
        from sniffer.commands.check import check
        from sniffer.capture.settings import CaptureSpec

        defaults = Tolerances()
        tol = Tolerances(
            time_ms=next(v for v in (time_tol_ms, self.time_tol, defaults.time_ms) if v is not None),
            latency_ms=next(v for v in (latency_tol_ms, self.lat_tol, defaults.latency_ms) if v is not None),
        )
        if isinstance(devices, (list, tuple)):
            from decoders.registry import parse_device_args

            devices = parse_device_args(list(devices))
        spec = CaptureSpec.of(baud=baud, parity=parity, stopbits=stopbits, devices=devices, protocol=protocol,
                              timeout_ms=timeout_ms, model_files=[str(self.base / m) for m in (model_files or [])])
        rc, text = check(self.base / capture, self.base / golden, spec=spec, tolerances=tol, update=self.update)
        if rc == EXIT_SAME:
            return text
        if rc == EXIT_DIFFERENT:
            pytest.fail(f"decode of {capture} differs from {golden} "
                        f"(pytest --update-golden rewrites it; review the diff):\n{text}", pytrace=False)
        pytest.fail(text.strip(), pytrace=False)
        return text  # pragma: no cover


@pytest.fixture
def sniffer_check(request) -> SnifferChecker:
    """A callable: sniffer_check(capture, golden, baud=..., devices={2: 'a510'}, time_tol_ms=...)."""
    cfg = request.config
    return SnifferChecker(Path(request.path).parent, cfg.getoption("--update-golden"),
                          cfg.getoption("--sniffer-time-tol-ms"), cfg.getoption("--sniffer-latency-tol-ms"))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item):
    """A test marked @pytest.mark.sniffer_golden(capture, golden, **options) checks that capture first."""
    marker = item.get_closest_marker("sniffer_golden")
    if marker is not None:
        if len(marker.args) != 2:
            pytest.fail("@pytest.mark.sniffer_golden needs (capture, golden, **options)", pytrace=False)
        cfg = item.config
        SnifferChecker(Path(item.path).parent, cfg.getoption("--update-golden"),
                       cfg.getoption("--sniffer-time-tol-ms"),
                       cfg.getoption("--sniffer-latency-tol-ms"))(*marker.args, **marker.kwargs)
    yield
