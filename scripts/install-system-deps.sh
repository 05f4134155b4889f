#!/usr/bin/env bash
# System packages the test suite uses (Debian's apt):
#   tshark             - checks that our pcap export decodes as Modbus/RTU in Wireshark;
#   chromium           - headless, drives the browser view (`sniffer serve`) with keys
#                        (tests/test_serve_chromium.py) and opens `sniffer report`'s page offline
#                        (tests/test_report_chromium.py; the report itself needs no system package);
#   fonts-dejavu-core  - a monospace font for the page's terminal;
#   mosquitto          - the MQTT broker the --mqtt tests start on a free port (tests/broker.py);
#   openssl            - the tests' CA and server certificate for the broker's TLS listener;
#   sigrok-cli         - decodes logic-analyzer captures (.sr files, live analyzers: `replay FILE.sr --rx`,
#                        `live sigrok:DRIVER`, `detect FILE.sr`); its UART decoder is what the sniffer reads
#                        (tests/test_sigrok_*.py, test_logic_detect.py).  Debian 12: sigrok-cli 0.7.2.
# Without them those tests skip with a reason, except the Chromium and sigrok-cli tests on CI (CI set),
# which fail, and the MQTT tests, which always fail without mosquitto (they need a real broker).
# Idempotent and non-interactive: installs only what is missing; does nothing (and succeeds) without
# root or passwordless sudo.
set -uo pipefail

missing=()
command -v tshark >/dev/null 2>&1 || missing+=(tshark)
command -v chromium >/dev/null 2>&1 || missing+=(chromium)
[ -e /usr/share/fonts/truetype/dejavu/DejaVuSansMono.ttf ] || missing+=(fonts-dejavu-core)
command -v mosquitto >/dev/null 2>&1 || [ -x /usr/sbin/mosquitto ] || missing+=(mosquitto)
command -v openssl >/dev/null 2>&1 || missing+=(openssl)
command -v sigrok-cli >/dev/null 2>&1 || missing+=(sigrok-cli)
if [ "${#missing[@]}" = 0 ]; then
  exit 0
fi
if [ "$(id -u)" = 0 ]; then
  SUDO=""
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
  SUDO="sudo -n"
else
  echo "install-system-deps: no root: not installing ${missing[*]} (tests that need them skip; on CI the browser test fails)" >&2
  exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
  echo "install-system-deps: no apt-get: install ${missing[*]} yourself (tests that need them skip; on CI the browser test fails)" >&2
  exit 0
fi
export DEBIAN_FRONTEND=noninteractive
# wireshark-common asks whether non-root users may capture: answer no, never prompt
echo "wireshark-common wireshark-common/install-setuid boolean false" | $SUDO debconf-set-selections 2>/dev/null || true
install() { $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}" >/dev/null 2>&1; }
install || { $SUDO apt-get update -q >/dev/null 2>&1 && install; } \
  || echo "install-system-deps: could not install ${missing[*]} (tests that need them skip; on CI the browser test fails)" >&2
exit 0
