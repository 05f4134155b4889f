import sys
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
