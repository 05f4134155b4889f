"""`sniffer simulate --fault`: every fault on every scenario either simulates or is refused in one line (exit 2).

A fault a scenario cannot carry (a drive trip on a PD-series drive, which has no register-level model; a
second Modbus master on a PD-series line) is said in one line before anything runs, never a traceback
half way through the simulation.  The command runs in-process (sniffer.cli.main, as the console script
calls it): an exception that is a bug escapes main and fails the test with its traceback.
"""

from __future__ import annotations

import pytest

from sniffer.cli import main
from sniffer.simulator.faults import KINDS
from sniffer.simulator.scenario import SCENARIOS

from helpers import decoded


@pytest.mark.parametrize("scenario", sorted(SCENARIOS))
def test_every_fault_simulates_or_is_refused_in_one_line(scenario, tmp_path, capsys):
    simulated = refused = 0
    for kind in KINDS:
        for arg in ("", ":2"):
            out = tmp_path / f"{kind}{arg.replace(':', '_')}.mcap"
            rc = main(["simulate", "--out", str(out), "--scenario", scenario, "--fault", kind + arg,
                       "--duration", "1", "--seed", "3"])
            err = capsys.readouterr().err.strip().splitlines()
            assert rc in (0, 2), (kind + arg, rc, err)
            if rc == 2:
                assert len(err) == 1 and err[0].startswith("sniffer: error: "), (kind + arg, err)
                assert not out.exists(), "a refused fault wrote nothing"
                refused += 1
                continue
            _, frames = decoded(str(out))
            assert frames, f"{scenario} --fault {kind}{arg}: no frame simulated"
            simulated += 1
    # every scenario carries some faults (the line's own: bus_unbiased, driver_enable_late) and a unit
    # number the scenario lacks is refused (wrong_line_settings:2 is a baud of 2)
    assert simulated >= 4 and refused >= 1, (simulated, refused)


@pytest.mark.parametrize("scenario,fault,says", [
    ("pd-series", "second_master:2", "polls with Modbus reads"),
    ("pd-series-ascii", "second_master", "polls with Modbus reads"),
    ("pd-series", "drive_fault", "needs a drive of a real model"),
    ("pd-series", "noise_correlated_with_load:2", "needs a drive of a real model"),
])
def test_what_a_pd_line_cannot_carry_is_said(scenario, fault, says, tmp_path, capsys):
    rc = main(["simulate", "--out", str(tmp_path / "x.mcap"), "--scenario", scenario, "--fault", fault])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and says in err and "\n" not in err, err
