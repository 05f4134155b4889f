"""The fast lane: which tests are `slow`, decided by one rule, and a guard that keeps the rule honest.

`pytest -m "not slow"` is what one runs while working; .ci/run runs everything.  A test is slow when it
runs real parts that take seconds to start or to settle: another process, a pseudo-terminal, Textual's
Pilot, a browser, an MQTT broker.  `is_slow` reads that from the code a test runs before it runs: the
test function, its fixtures, and (transitively) the helpers in tests/ they call, looking for the names
in SLOW_NAMES.  So a test added later is marked by the same rule, without a marker of its own.  What
the names cannot show (a command run in this process that starts a capture child, a long simulation)
is in SLOW_FILES / SLOW_TESTS, and `pytest.mark.slow` on a test still works.

The guard (`Guard`) watches, while a test runs that the lane kept, for what the rule is about:
subprocess.Popen, os.fork, os.openpty and App.run_test.  A test that starts one fails with a line
saying so and how to mark it, so the lane cannot quietly slow down again.
"""

from __future__ import annotations

import inspect
import os
import subprocess
import sys
import types
from pathlib import Path

TESTS = Path(__file__).resolve().parent

# a name in the code a test runs -> why that makes it slow
SLOW_NAMES: dict[str, str] = {
    "run_test": "Textual's Pilot (App.run_test)",
    "snap_compare": "Textual's Pilot (a snapshot)",
    "Popen": "another process",
    "subprocess": "another process",
    "multiprocessing": "another process",
    "fork": "another process",
    "openpty": "a pseudo-terminal",
    "pty": "a pseudo-terminal",
    "PtyBus": "a pseudo-terminal (the simulator's bus)",
    "PtyLine": "a pseudo-terminal (the simulator's UART line)",
    "ReaderProcess": "another process (the serial reader)",
    "CaptureProcess": "another process (the capture child)",
    "PublishSink": "another process (a viewers' socket publisher)",
    "SigrokSource": "another process (sigrok-cli)",
    "need_sigrok_cli": "another process (sigrok-cli decodes the samples)",
    "LocalCluster": "other processes (a Dask cluster)",
    "StdioServerParameters": "another process (an MCP server over stdio)",
}
# the commands that start processes or ptys of their own (a capture child, the port's reader, a simulated
# line): a test that runs one in this process (`main(["live", ...])`) is slow
SLOW_COMMANDS: frozenset[str] = frozenset({"live", "demo", "serve", "attach"})
# whole files that are slow by what every test in them does
SLOW_FILES: frozenset[str] = frozenset({
    "test_diagnose_sweeps.py",  # seeded sweeps of simulated plants through diagnose: minutes in all
    "test_unattended_live.py",  # `live` on ptys for minutes: segments, SIGKILL, wait-port
    "test_trigger_day.py",  # four simulated hours replayed
    "test_segments.py",  # every test writes a rotated set of MCAP segments and replays it
    "test_ingest_whole.py",  # every test ingests captures into a dataset and queries it with DuckDB
    "test_parallel.py",  # worker processes decode the parts (sniffer.parallel)
    "test_parallel_fleet.py",  # worker processes or a local Dask cluster take captures into a dataset
    "test_parallel_links.py",  # worker processes decode captures of one, two and three simulated links
})
# single tests slow by their work (seconds of simulation, decoding or memory tracing), not by a part the rule
# sees: "file.py::test_name", parameters left out.  `pytest -m "not slow" --durations=30` shows candidates.
SLOW_TESTS: frozenset[str] = frozenset({
    "test_diagnose_masters.py::test_each_second_master_form_is_found_on_the_unit_it_polls",  # 8 plants x 60 s each
    "test_diagnose_masters.py::test_healthy_plants_give_nothing_above_info",  # 8 plants x 60 s
    "test_diagnose_masters.py::test_busy_healthy_plants_give_nothing_above_info",  # 8 busy plants x 30 s
    "test_diagnose_masters.py::test_a_timeout_exceeded_by_the_slowest_answers_only_is_found_with_a_timeout_to_set",
    "test_diagnose_masters.py::test_a_silent_unit_only_written_is_silent_and_its_retries_are_no_echoes",  # 8 x 50 s
    # minutes of simulated line through diagnose
    "test_diagnose_thresholds.py::test_a_full_line_is_not_nothing_to_fix_and_a_warning_once_it_stretches",
    "test_diagnose_thresholds.py::test_strays_after_0_7_percent_of_transmissions_are_bus_unbiased_with_their_rate",
    "test_diagnose_episodes.py::test_a_silence_that_comes_twice_is_two_episodes",
    "test_diagnose_episodes.py::test_every_kind_found_says_when_in_episodes",  # five captures of 60 s
    # several captures into a dataset: by worker processes, as `--jobs` defaults to every core
    "test_dataset.py::test_ingest_is_incremental",
    "test_dataset.py::test_query_formats_and_presets",
    "test_dataset.py::test_corrupt_capture_is_left_out_whole",
    "test_dataset.py::test_export_of_a_rotated_folder_takes_its_segments",
    "test_value_parts.py::test_a_dataset_of_segments_keeps_one_unit_per_name",
    "test_simulated_models.py::test_every_simulated_frame_recovered_and_paired",
    "test_simulate_faults.py::test_every_fault_simulates_or_is_refused_in_one_line",  # 264 short simulations
    "test_sources_stream.py::test_memory_does_not_grow_with_the_file",
    "test_sources_stream.py::test_long_single_channel_run_is_cut_at_4096_bytes",
    "test_sources_stream.py::test_two_channels_written_apart_are_merged_by_time",
    "test_mcap.py::test_cut_files_read_a_prefix",
    "test_bad_input.py::test_every_model_key_read_by_the_code_is_checked_before_it_is_used",
    "test_foxglove_files.py::test_every_message_fits_its_channels_schema",
    "test_foxglove_files.py::test_export_and_replay_of_a_foxglove_capture",
    "test_session.py::test_export_replaces_the_old_output_only_when_complete",
    "test_tui_history.py::test_thinned_history_is_bounded_and_true_to_the_capture",
    "test_links_order.py::test_a_rotated_capture_replays_from_its_folder_in_the_order_it_went_out",
    "test_links_order.py::test_frames_of_every_link_go_out_in_time_order_in_every_view",
    "test_mqtt_losses.py::test_a_broker_that_accepts_and_never_answers_holds_the_end_no_longer_than_close_allows",
    "test_dataset.py::test_query_read_only_gives_the_same_answers_and_no_access",
    "test_dataset.py::test_export_two_captures_as_segments",
    "test_pcap_damage.py::test_no_bit_flip_of_a_pcapng_packet_header_or_interface_loses_bytes_silently",
    "test_identify_precision.py::test_user_map_of_the_right_model_is_not_contradicted",
    "test_uart_line.py::test_simulate_receiver_settings_record_what_that_uart_received",
    "test_pytest_plugin.py::test_missing_golden_fails_then_update_then_pass",
    "test_pytest_plugin.py::test_tolerance_option",
    "test_simulator.py::test_usb_packets_frame_at_a_time_equal_byte_by_byte",
    "test_simulator.py::test_framer_recovers_simulated_frames_from_wire",
    "test_simulator.py::test_crc_valid_unless_damaged_and_lengths_fit_function",
    "test_detect_search.py::test_each_line_is_found_certain",
    "test_detect_search.py::test_a_rate_not_tried_fits_nothing_until_asked_for",
    "test_report_bad_input.py::test_damaged_capture_is_reported_on_and_exits_2",
    "test_giveway.py::test_gives_way_only_while_frames_come_in_and_leaves_nothing_behind",
})
CPU_NOTE_S = 2.0  # a lane test that takes more CPU than this is named at the end of the run (a candidate)


def _code_objects(code: types.CodeType):
    yield code
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            yield from _code_objects(const)


def _strings(consts):
    """The string constants of a code object, those folded into tuples (`["live", PORT]`) included."""
    for k in consts:
        if isinstance(k, str):
            yield k
        elif isinstance(k, (tuple, frozenset)):
            yield from _strings(k)


def _in_tests(obj) -> bool:
    try:
        path = inspect.getsourcefile(obj)
    except TypeError:
        return False
    return bool(path) and Path(path).resolve().parent == TESTS


class Rule:
    """What makes a test slow, from the names its code (and the tests/ helpers it calls) uses; cached per
    function, as many tests share helpers."""

    def __init__(self) -> None:
        self._seen: dict[int, str | None] = {}

    def why(self, func) -> str | None:
        """Why `func` is slow (a sentence), or None."""
        func = inspect.unwrap(getattr(func, "__func__", func))
        key = id(func)
        if key in self._seen:
            return self._seen[key]
        self._seen[key] = None  # a cycle of helpers: not slow by the cycle itself
        why = self._why(func)
        self._seen[key] = why
        return why

    def _why(self, func) -> str | None:
        code = getattr(func, "__code__", None)
        if code is None:
            return None
        spaces = [getattr(func, "__globals__", {})]
        for value in list(spaces[0].values()):  # helper modules of tests/ imported whole (`import terminal`)
            if isinstance(value, types.ModuleType) and _in_tests(value):
                spaces.append(vars(value))
        for c in _code_objects(code):
            if "main" in c.co_names:
                command = next((k for k in _strings(c.co_consts) if k in SLOW_COMMANDS), None)
                if command:
                    return f"runs `sniffer {command}`: processes or ptys of its own"
            for name in c.co_names:
                if name in SLOW_NAMES:
                    return f"uses {name}: {SLOW_NAMES[name]}"
                module = sys.modules.get(name)
                if isinstance(module, types.ModuleType) and _in_tests(module) and vars(module) not in spaces:
                    spaces.append(vars(module))  # imported inside the function
                for space in spaces:
                    why = self._why_of(space.get(name))
                    if why:
                        return why
        return None

    def _why_of(self, obj) -> str | None:
        if isinstance(obj, types.FunctionType) and _in_tests(obj):
            return self.why(obj)
        if isinstance(obj, type) and _in_tests(obj):
            for member in vars(obj).values():
                why = self._why_of(getattr(member, "__func__", member))
                if why:
                    return why
        return None


def slow_reason(item, rule: Rule) -> str | None:
    """Why the rule makes `item` slow, or None."""
    path = Path(str(item.fspath))
    if path.name in SLOW_FILES:
        return "listed in SLOW_FILES"
    name = getattr(item, "originalname", None) or item.name
    if f"{path.name}::{name}" in SLOW_TESTS:
        return "listed in SLOW_TESTS"
    func = getattr(item, "function", None)
    if func is not None and getattr(func, "is_hypothesis_test", False):
        return "hypothesis: seeded fuzzing"
    if func is not None:
        why = rule.why(func)
        if why:
            return why
    info = getattr(item, "_fixtureinfo", None)
    for fname in getattr(item, "fixturenames", ()):
        if fname in SLOW_NAMES:
            return f"fixture {fname}: {SLOW_NAMES[fname]}"
        for fdef in (info.name2fixturedefs.get(fname, ()) if info else ()):
            why = rule.why(fdef.func) if _in_tests(fdef.func) else None
            if why:
                return f"fixture {fname} {why}"
    return None


class Guard:
    """While a test the lane kept runs, what it starts that the rule is about; `used` names it."""

    def __init__(self) -> None:
        self.used: list[str] = []
        self.watching = False
        self._undo: list = []

    def install(self) -> None:
        self._wrap(subprocess.Popen, "__init__", "started a process (subprocess.Popen)")
        self._wrap(os, "fork", "forked a process (os.fork)")
        self._wrap(os, "openpty", "opened a pseudo-terminal (os.openpty)")
        try:
            from textual.app import App
        except ImportError:
            return
        self._wrap(App, "run_test", "ran Textual's Pilot (App.run_test)")

    def uninstall(self) -> None:
        for owner, attr, original in reversed(self._undo):
            setattr(owner, attr, original)
        self._undo.clear()

    def _wrap(self, owner, attr: str, what: str) -> None:
        original = getattr(owner, attr)
        guard = self

        def watched(*args, **kw):
            if guard.watching and what not in guard.used:
                guard.used.append(what)
            return original(*args, **kw)

        watched.__wrapped__ = original
        self._undo.append((owner, attr, original))
        setattr(owner, attr, watched)
