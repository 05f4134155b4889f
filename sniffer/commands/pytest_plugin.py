"""pytest plugin: check your own captures against reviewed golden decodes.

Installed with the package (entry point `pytest11: sniffer`).  In a test:

    def test_line3(sniffer_check):
        sniffer_check("captures/line3.mcap", "golden/line3.txt")

    @pytest.mark.sniffer_golden("captures/line3.csv", "golden/line3.txt", baud=19200, parity="E")
    def test_line3_marker():
        pass  # the marker runs the check before the test body

Relative paths count from the test file's folder.  A difference fails the
test as an assertion with `sniffer check`'s summary (frames that differ, the
first difference, the differences by unit and field, findings added or gone;
`--sniffer-diff` adds the unified diff); `pytest --update-golden` rewrites the
goldens (then review them with git diff).  Tolerances: keyword arguments
`time_tol_ms` / `latency_tol_ms` / `ignore=[...]` / `tolerance=["Output current=0.2A"]`,
or `--sniffer-time-tol-ms` / `--sniffer-latency-tol-ms` for the whole run (and
whatever the golden's header keeps).
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
    g.addoption("--sniffer-diff", action="store_true", default=False,
                help="a failing sniffer_check shows the unified diff after its summary")


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "sniffer_golden(capture, golden, **options): check CAPTURE's decode against GOLDEN "
        "before the test body",
    )


class SnifferChecker:
    def __init__(self, base: Path, update: bool, time_tol: float | None, lat_tol: float | None,
                 diff: bool = False) -> None:
        self.base = base
        self.update = update
        self.time_tol = time_tol
        self.lat_tol = lat_tol
        self.diff = diff

    def __call__(self, capture, golden, *, baud=None, parity=None, stopbits=None, devices=None,
                 protocol=None, timeout_ms=None, model_files=None, time_tol_ms=None,
                 latency_tol_ms=None, ignore=(), tolerance=()) -> str:
        """Check; returns the golden text path's message on update. Fails the test on a difference."""
        __tracebackhide__ = True  # the failure is the summary, not this function's source
        from sniffer.analysis.check import EXIT_DIFFERENT, EXIT_SAME
        from sniffer.analysis.goldenfields import FieldRules, parse_tolerance
        from sniffer.commands.check import check_outcome
        from sniffer.capture.settings import CaptureSpec

        try:
            rules = FieldRules(tuple(ignore), tuple(parse_tolerance(t) for t in tolerance))
        except ValueError as e:
            pytest.fail(f"sniffer_check: {e}", pytrace=False)
        if isinstance(devices, (list, tuple)):
            from decoders.registry import parse_device_args

            devices = parse_device_args(list(devices))
        spec = CaptureSpec.of(baud=baud, parity=parity, stopbits=stopbits, devices=devices, protocol=protocol,
                              timeout_ms=timeout_ms, model_files=[str(self.base / m) for m in (model_files or [])])
        o = check_outcome(self.base / capture, self.base / golden, spec=spec, update=self.update,
                          time_ms=next((v for v in (time_tol_ms, self.time_tol) if v is not None), None),
                          latency_ms=next((v for v in (latency_tol_ms, self.lat_tol) if v is not None), None),
                          rules=rules)
        if o.rc == EXIT_SAME:
            return o.message
        if o.rc == EXIT_DIFFERENT:
            # an AssertionError, so pytest shows it as a failed assertion: its lines under "E", no wall
            raise AssertionError(f"decode of {capture} differs from {golden} (pytest --update-golden rewrites "
                                 f"it; review the diff)\n{o.summary.text(self.diff, hint=_HINT)}".rstrip("\n"))
        pytest.fail(o.message.strip(), pytrace=False)
        return o.message  # pragma: no cover


_HINT = "  pytest --sniffer-diff shows the unified diff"


@pytest.fixture
def sniffer_check(request) -> SnifferChecker:
    """A callable: sniffer_check(capture, golden, baud=..., devices={2: 'a510'}, time_tol_ms=...)."""
    cfg = request.config
    return SnifferChecker(Path(request.path).parent, cfg.getoption("--update-golden"),
                          cfg.getoption("--sniffer-time-tol-ms"), cfg.getoption("--sniffer-latency-tol-ms"),
                          cfg.getoption("--sniffer-diff"))


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
                       cfg.getoption("--sniffer-latency-tol-ms"),
                       cfg.getoption("--sniffer-diff"))(*marker.args, **marker.kwargs)
    yield
