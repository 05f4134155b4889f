"""The ACME Link decoder: registers read and written, by their names in the manual (chapter 9.4)."""

from sniffer.codes import ERROR, WARNING, Code, note

ERROR_REPLY = Code("acme.error", WARNING, "the drive refused the command (error reply)", "exception")
SHORT = Code("acme.short", ERROR, "the data is shorter than its command needs")
# address: (id in the manual, name, scale, unit)
REGISTERS = {
    0x00: ("P-00", "Speed setpoint", 0.1, "Hz"),
    0x01: ("P-01", "Output frequency", 0.1, "Hz"),
    0x02: ("P-02", "Motor current", 0.01, "A"),
    0x03: ("P-03", "Fault code", 1, None),
}
ERRORS = {1: "UNKNOWN COMMAND", 2: "BAD ADDRESS", 3: "LOCKED WHILE RUNNING"}


class AcmeDecoder:
    model = "acme-vfd"
    family = "acme-link"  # the protocol its frames come in (--device checks it)
    codes = (ERROR_REPLY, SHORT)

    def decode(self, frame, request, state) -> None:
        adu = frame.adu
        cmd, data = frame.function, adu[3:]
        if cmd & 0x80:
            code = data[0] if data else None
            frame.exception = {"code": code, "name": ERRORS.get(code, "ERROR")}
            frame.annotations.append(note(ERROR_REPLY, f"error {code}: {ERRORS.get(code, '?')}", 4, 4 + len(data)))
            frame.summary = f"error reply {ERRORS.get(code, code)}"
            return
        need = {0x01: 3, 0x02: 4}.get(cmd, 0)
        if len(data) < need:
            frame.annotations.append(note(SHORT, f"{len(data)} data bytes, command {cmd:02X}H needs {need}",
                                          3, len(frame.raw)))
            return
        if cmd == 0x01 and frame.role_fits & 2:  # a read's answer: address, count, then the values
            start, n = int.from_bytes(data[0:2], "big"), data[2]
            values = [int.from_bytes(data[3 + 2 * i:5 + 2 * i], "big") for i in range(min(n, (len(data) - 3) // 2))]
            frame.points = [self._point(start + i, v, 7 + 2 * i) for i, v in enumerate(values)]
            if values:
                state.commit(frame, "holding", start, values)
            frame.summary = " ".join(f"{p['name']}={p['value']}{' ' + p['unit'] if p['unit'] else ''}"
                                     for p in frame.points)
        elif cmd == 0x01:
            start, n = int.from_bytes(data[0:2], "big"), data[2]
            frame.summary = f"read {start:02X}H..{start + n - 1:02X}H ({n})"
        elif cmd == 0x02:
            addr, v = int.from_bytes(data[0:2], "big"), int.from_bytes(data[2:4], "big")
            frame.points = [self._point(addr, v, 6)]
            if frame.role_fits & 2:
                state.commit(frame, "holding", addr, [v])
            p = frame.points[0]
            frame.summary = f"write {p['name']}={p['value']}{' ' + p['unit'] if p['unit'] else ''}"

    @staticmethod
    def _point(addr: int, raw: int, at: int) -> dict:
        pid, name, scale, unit = REGISTERS.get(addr, ("", f"register {addr:02X}H", 1, None))
        value = round(raw * scale, 6) if scale != 1 else raw
        return {"name": name, "address": addr, "raw": raw, "value": value, "unit": unit, "id": pid,
                "span": [at, at + 2]}
