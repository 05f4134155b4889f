#!/usr/bin/env bash
# System packages the test suite can use but does not require (tests skip, with a reason, without them):
#   tshark - checks that our pcap export decodes as Modbus/RTU in Wireshark.
# Idempotent and non-interactive; does nothing (and succeeds) without root or passwordless sudo.
set -uo pipefail

if command -v tshark >/dev/null 2>&1; then
  exit 0
fi
if [ "$(id -u)" = 0 ]; then
  SUDO=""
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
  SUDO="sudo -n"
else
  echo "install-system-deps: no root: skipping tshark (pcap export tests will be skipped)" >&2
  exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
  echo "install-system-deps: no apt-get: install tshark yourself (pcap export tests will be skipped)" >&2
  exit 0
fi
export DEBIAN_FRONTEND=noninteractive
# wireshark-common asks whether non-root users may capture: answer no, never prompt
echo "wireshark-common wireshark-common/install-setuid boolean false" | $SUDO debconf-set-selections 2>/dev/null || true
$SUDO apt-get install -y -q tshark >/dev/null 2>&1 \
  || { $SUDO apt-get update -q >/dev/null 2>&1 && $SUDO apt-get install -y -q tshark >/dev/null 2>&1; } \
  || echo "install-system-deps: could not install tshark (pcap export tests will be skipped)" >&2
exit 0
