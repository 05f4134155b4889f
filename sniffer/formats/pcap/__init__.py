"""pcap / pcapng: the format, its reader and its writer."""
