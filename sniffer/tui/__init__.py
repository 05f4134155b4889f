"""Textual TUI: a sink (sink.py) feeding a Textual-free store (model.py) that the App views.

Entry points for the CLI are in `sniffer.tui.run` (replay_tui, live_tui, demo_tui, run_tui).
"""
