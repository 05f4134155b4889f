"""What the coordinator knows for certain at the cut before the next part: the check a part decoded ahead must pass.

A part is decoded from a guess of the decoders' state at its cut (what the truth
was when it was handed out).  Once every part before it is taken, the truth at its
cut is: the pipeline's state where the part before ended (its cut state), the
decoders' naming (each link's registry in this process, which observed every
frame the parts before observed), and every unit's memory (the memory at the
start, with what each part wrote).  The part is taken (`take`) if its cut and
pipeline state are the same, the naming is the same, every value it read
without writing it first is the true one, and every frame it observed gets the
same notes when observed again here (`DecoderRegistry.replay`, which moves the
naming on).  Then its writes and end move the truth on.
"""

from __future__ import annotations

from sniffer.parallel.part import Counted


class Truth:
    """The decoders' state at the next part's cut, per link, and where that cut is."""

    def __init__(self, registries: dict) -> None:
        """`registries`: {link: DecoderRegistry} at the start of the capture; they follow the parts taken."""
        self.regs = registries
        self.shadow = {link: dict(reg.snapshot()["states"]) for link, reg in registries.items()}
        self.cut = 0  # the next part starts at this event
        self.state: tuple | None = None  # the pipeline's cut state there (None: the start, fresh)
        self.base = 0  # and its first frame's number

    def guess(self) -> dict:
        """{link: registry snapshot}: what a part is decoded with (exact for the part at the cut)."""
        return {link: {"states": self.shadow[link], **reg.identity_state()} for link, reg in self.regs.items()}

    def take(self, c: Counted) -> str | None:
        """Take part `c` if it was decoded as the whole capture decodes it, and move on to its end; else say
        why not (and stay)."""
        if c.cut is None:
            return c.why or "no cut"
        if c.cut != self.cut:
            return f"cut at event {c.cut}, the part before ended at {self.cut}"
        if self.state is not None and c.state != self.state:
            return "the pipeline's state at the cut differs"
        for link, naming in c.identity.items():
            if naming != self.regs[link].naming():
                return f"units named otherwise at the cut{f' on link {link}' if link else ''}"
        for link, reads in c.reads.items():
            shadow = self.shadow[link]
            for (unit, table, key), (known, value) in reads.items():
                d = shadow.get(unit, {}).get(table, {})
                if (key in d) != known or (known and d[key] != value):
                    return f"unit {unit} {table} {key} read as {value if known else 'unknown'} from a guess"
        saved = {link: reg.identity_state() for link, reg in self.regs.items()}
        for link, observed in c.observed.items():
            why = self.regs[link].replay(observed)
            if why is not None:
                for back, reg in self.regs.items():
                    reg.restore({"states": {}, **saved[back]})
                return why
        for link, units in c.writes.items():
            shadow = self.shadow[link]
            for unit, tables in units.items():
                st = shadow.setdefault(unit, {})
                for table, values in tables.items():
                    st.setdefault(table, {}).update(values)
        self.cut, self.state = c.end, c.end_state
        self.base += c.frames
        return None
