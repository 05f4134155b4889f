"""One table of output formats (sniffer.formats.TABLE): every list of them is read from it."""

from __future__ import annotations

import argparse

from sniffer.formats import EXPORT_FORMATS, STREAM_FORMATS, TABLE, TUI_FORMATS, WRITERS


def _choices(argv_cmd: str, flag: str):
    from sniffer.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[argv_cmd]
    return next(a for a in sub._actions if flag in a.option_strings)


def test_the_stream_formats_are_the_replay_choices_and_each_has_a_stdout_sink():
    from sniffer.capture.settings import CaptureSpec
    from sniffer.commands.common import stream_sink

    action = _choices("replay", "--format")
    assert tuple(action.choices) == STREAM_FORMATS and action.default == STREAM_FORMATS[0] == "text"
    for fmt in STREAM_FORMATS:
        assert stream_sink(CaptureSpec(stream=fmt), line_buffered=False) is not None, fmt


def test_every_format_written_by_parts_has_a_part_plan():
    from sniffer.formats import FileSink
    from sniffer.parallel.outputs import split

    for f in TABLE:
        if f.parts and not f.extra:
            plan, writer = split(FileSink(f.name, f"/tmp/x{f.suffixes[0]}"))
            assert hasattr(plan, "part_sink") and writer.outputs, f.name


def test_the_tui_dialog_and_completion_read_the_table():
    from sniffer.commands.completion import _formats as export_formats
    from sniffer.tui.export import FORMATS

    assert FORMATS is TUI_FORMATS and list(FORMATS) == ["mcap", "pcap", "csv"]
    assert all(WRITERS[f].suffixes[0] == ext for f, ext in FORMATS.items())
    assert tuple(export_formats()) == (*EXPORT_FORMATS, "dataset")
