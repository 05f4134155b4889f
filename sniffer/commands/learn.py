"""`sniffer learn CAPTURE --out map.toml`: a skeleton register map from a capture's traffic (sniffer.analysis.learn).

The map's model id is the output file's stem; it loads with --model-file and decodes the same
capture with its placeholder names.  Written as NAME.part and renamed when complete; an output
that is also the input is refused before the capture is read.
"""

from __future__ import annotations

import os

from sniffer.formats.outputs import Output, shown
from sniffer.decoding import decode
from sniffer.capture.settings import CaptureSpec
from sniffer.commands.common import EXIT_USAGE, UsageError, report, say
from sniffer.commands.flags import command_parser, decode_flags, input_flags, serial_flags
from sniffer.commands.replay import file_source


def add_parser(subparsers) -> None:
    p = command_parser(
        subparsers, "learn", help="a skeleton register map (registers.toml) from a capture's traffic, to name",
        description="""\
            A register map for a device without one: every register the capture reads or writes, its block,
            a guessed type (u16, s16, u32, float ...) and placeholder names, for you to fill in from the
            manual (docs/register-map-format.md).  It decodes the same capture at once.""",
        examples=["sniffer learn pump.mcap --out pump.toml",
                  "sniffer replay pump.mcap --model-file pump.toml --device 3=pump"])
    input_flags(p)
    p.add_argument("--out", required=True, metavar="FILE.toml",
                   help="the map to write; its stem is the model id (--model-file FILE.toml --device UNIT=STEM)")
    serial_flags(p, "file")
    decode_flags(p, "file")


def run(spec: CaptureSpec, args) -> int:
    from decoders.tables import MapError, load_map

    from sniffer.analysis.learn import Learner

    if not spec.out.lower().endswith(".toml"):
        raise UsageError(f"--out {shown(spec.out)}: the skeleton is a register map, give a .toml file name")
    out = Output(spec.out, inputs=spec.read_paths())  # checked before the input is read
    model_id = os.path.splitext(os.path.basename(out.path))[0]
    learner = Learner()
    session = decode(spec, file_source(spec))
    from sniffer.protocols import PROTOCOLS

    try:
        for f in session:
            proto = PROTOCOLS.get(f.protocol)
            if proto is not None and proto.family != "modbus":
                out.discard()
                say(f"error: {shown(spec.input)}: {f.protocol} frames: learn writes Modbus register maps, and "
                    f"{f.protocol} has its own parameter table (decoders/pd_series)")
                return EXIT_USAGE
            learner.frame(f)
    except BaseException:
        out.discard()
        raise
    rc = report(session, label=spec.input)
    if session.error and not session.damage:
        out.discard()
        return rc
    if not learner.regs:
        out.discard()
        say(f"error: {shown(spec.input)}: no register reads or writes (fc 03/04/06/10) to learn from")
        return EXIT_USAGE
    regmap = learner.to_map(model_id, spec.input)
    text = learner.to_toml(model_id, spec.input, out.path, regmap)
    try:
        out.write_text(text)
        load_map(out.part)  # what we write must load (a bug here is ours, not the user's)
    except (OSError, MapError):
        out.discard()
        raise
    out.commit()
    rows = [*regmap.registers.values(), *regmap.inputs.values()]
    guessed = sum(1 for r in rows if r.type != "u16")
    say(f"wrote {out.path}: {len(learner.units)} units, {len(learner.blocks)} blocks, "
        f"{len(rows)} registers ({guessed} typed other than u16); "
        f"decode with --model-file {out.path} --device UNIT={model_id}")
    return rc
