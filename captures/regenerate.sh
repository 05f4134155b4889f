#!/usr/bin/env bash
# Rebuild the simulated sample captures and every golden decode.
# Review the golden diff before committing it: a changed golden is a changed verdict.
set -euo pipefail
cd "$(dirname "$0")/.."
S=".venv/bin/sniffer"
sim() { "$S" simulate --scenario "$1" --duration "$2" --seed 11 --out "captures/sim/$1.mcap"; }
sim default 4
sim errors 6
sim fast 1
for m in tds-v8 a510 a510-ascii spl spl-ascii pd-series pd-series-ascii; do sim "$m" 10; done

UPDATE_GOLDEN=1 .venv/bin/python -m pytest -q tests/test_golden.py
