"""Third-party drive models and line protocols, found through entry points of ordinary Python packages.

    rs485_sniffer.models      a decoder (model, codes, decode), a zero-argument factory of one, or a register
                              map file (TOML, CSV, Home Assistant YAML) as a path
    rs485_sniffer.protocols   a ProtocolPlugin: a framer class and the decoder of its frames

entry.py: reading the groups and loading an entry (a plugin that fails to import or has a wrong interface is
one warning line naming it, and is left out); models.py and protocols.py: each group's checks.  Nothing is
registered anywhere: sniffer.protocols and decoders.registry ask for the plugins when they build their tables.
docs/plugins.md says how to write one.
"""

from sniffer import face

__all__ = ["Broken", "Plugin", "ProtocolPlugin", "broken", "model_plugins", "protocol_names", "protocol_plugins"]
__getattr__ = face(__name__, {
    "Broken": "sniffer.plugins.entry", "Plugin": "sniffer.plugins.entry", "broken": "sniffer.plugins.entry",
    "model_plugins": "sniffer.plugins.models", "ProtocolPlugin": "sniffer.plugins.protocols",
    "protocol_names": "sniffer.plugins.protocols", "protocol_plugins": "sniffer.plugins.protocols",
})
