"""Run one fuzz target under atheris (coverage-guided, libFuzzer): `python fuzz/run.py TARGET [libFuzzer flags]`.

    python fuzz/run.py mcap -max_total_time=600                 # ten minutes; new inputs into a scratch folder
    python fuzz/run.py framers -runs=0 fuzz/corpus/framers      # replay the seeds only
    python fuzz/run.py all -max_total_time=20                   # every target in one process (the suite's run)
    python fuzz/run.py --list                                   # the targets

`all` is every target behind one fuzzer: an input's first byte picks the target (its index in
targets.TARGETS, modulo their number), the rest is that target's input; its seeds are every target's,
each behind its byte.  One process to start (instrumenting the sniffer's modules takes seconds), and
the coverage of all of them guides it.

With no corpus folder given, new inputs go into a scratch folder and the target's seeds
(fuzz/corpus/TARGET) are read after it; a crash is written as ./crash-HASH (-artifact_prefix= moves it)
with its traceback on stderr.  docs/fuzzing.md says how a crash becomes a test.  atheris is in the
`fuzz` extra (pip install -e '.[fuzz]').
"""

from __future__ import annotations

import os
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)


def main() -> None:
    import atheris

    args = sys.argv[1:]
    if not args or args[0] in ("-h", "--help", "--list"):
        from targets import TARGETS

        print("targets: " + " ".join(TARGETS))
        sys.exit(0 if args else 2)
    name, flags = args[0], args[1:]
    with atheris.instrument_imports(include=["sniffer", "decoders"]):
        import targets  # noqa: F401 - the sniffer's modules are imported (and instrumented) as targets use them
        from targets import CORPUS, TARGETS, one

        # what a target reaches only later (the CLI imports a command's module when it runs) is instrumented now
        for module in ("sniffer.cli", "sniffer.commands", "sniffer.sources.files", "sniffer.framing.rtu",
                       "sniffer.framing.ascii", "sniffer.framing.pd", "sniffer.filterlang.parser",
                       "sniffer.formats.mcap.reader", "sniffer.formats.pcap.reader", "sniffer.formats.bytecsv.reader",
                       "sniffer.formats.saleae", "sniffer.sources.srzip", "sniffer.capture.busfile",
                       "decoders.tables", "decoders.mapformats.csvmap", "decoders.mapformats.hayaml",
                       "sniffer.analysis.check", "sniffer.diagnose.reference", "sniffer.commands.status"):
            try:
                __import__(module)
            except ImportError:
                pass
    names = list(TARGETS)
    if name != "all" and name not in TARGETS:
        sys.exit(f"fuzz/run.py: unknown target {name!r}; targets: all {' '.join(TARGETS)}")
    if not any(not f.startswith("-") for f in flags):  # no corpus folder: a scratch one, then the seeds
        flags += [tempfile.mkdtemp(prefix=f"fuzz-{name}-"), all_seeds(names) if name == "all" else str(CORPUS / name)]

    def test_one_input(data: bytes) -> None:
        if name != "all":
            one(name, data)
        elif data:
            one(names[data[0] % len(names)], data[1:])

    atheris.Setup([sys.argv[0], *flags], test_one_input)
    atheris.Fuzz()


def all_seeds(names: list[str]) -> str:
    """A folder of every target's corpus, each input behind its target's byte (the `all` target's seeds)."""
    from targets import CORPUS

    folder = tempfile.mkdtemp(prefix="fuzz-all-seeds-")
    for i, name in enumerate(names):
        for path in sorted((CORPUS / name).iterdir()):
            with open(os.path.join(folder, f"{name}-{path.name}"), "wb") as f:
                f.write(bytes([i]) + path.read_bytes())
    return folder


if __name__ == "__main__":
    main()
