"""Where decoded frames go: text, JSONL, MCAP (sniffer.mcap_sink), the TUI."""
