import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))


@pytest.fixture(scope="session")
def stress_mcap(tmp_path_factory) -> str:
    """One second of the simulator's stress scenario, written once per test session (tui_helpers)."""
    from tui_helpers import write_stress_capture

    return write_stress_capture(tmp_path_factory.mktemp("stress"))
