"""The outputs written by one writer over the whole capture, decoded by parts: MCAP and Parquet.

An MCAP file's chunks, message indexes, channels and summary, and a Parquet file's
row groups, depend on everything written before them, so the coordinator writes
them, with the same writer one process uses; the workers do what each frame costs:

    mcap      the part's messages, encoded (/raw events, /frames records), in the order the sink
              gets them; the coordinator's McapSink writes them (`McapSink.encoded`: the Foxglove
              channels are made from the records as a trigger window's are)
    parquet   the part's frame and point rows as Arrow tables (Arrow IPC), with each frame's number
              of points; the coordinator cuts them into the record batches one process makes
              (TableSink: CONVERT frames, and points up to the frame where CONVERT is reached) and
              writes them into row groups (RowGroupFile)
"""

from __future__ import annotations

from array import array

from sniffer.sinks.base import Sink


class McapPlan:
    wants_raw = True

    def part_sink(self, info, first: bool):
        return _Messages()


class _Messages(Sink):
    wants_raw = True

    def __init__(self) -> None:
        self.messages: list = []
        self.trailer: list = []  # frames one process writes after the next part's first event
        self.t0 = 0

    def start(self, info) -> None:
        self.t0 = info.t0_ns

    def raw(self, event) -> None:
        from sniffer.formats.mcap.format import encode_event

        self.messages.append((True, event.t_ns, encode_event(event)))

    def frame(self, f) -> None:
        from sniffer.formats.records import frame_json

        self.messages.append((False, f.t_ns, frame_json(f, self.t0)))

    def after(self, f) -> None:
        from sniffer.formats.records import frame_json

        self.trailer.append((False, f.t_ns, frame_json(f, self.t0)))

    def piece(self):
        return self.messages, self.trailer


class McapWriter:
    """The parts' messages into the MCAP sink a FileSink("mcap") opens (its outputs: the part file)."""

    def __init__(self, file_sink) -> None:
        self.outputs = file_sink.outputs
        self.file_sink = file_sink
        self.sink = None
        self.held: list = []  # the part before's trailer: after this part's first event

    def begin(self, info) -> None:
        self.sink = self.file_sink.open()
        self.sink.start(info)

    def add(self, piece) -> None:
        put = self.sink.encoded
        messages, trailer = piece
        held, self.held = self.held, trailer
        for k, (raw, t_ns, data) in enumerate(messages):
            put("raw" if raw else "frame", t_ns, data)
            if k == 0 and held:
                for _raw, t2, data2 in held:
                    put("frame", t2, data2)
                held = []
        for _raw, t_ns, data in held:  # no event followed (cannot happen: a part ends before an event)
            put("frame", t_ns, data)

    def close(self) -> None:
        if self.sink is not None:
            self.sink.close()


class ParquetPlan:
    def part_sink(self, info, first: bool):
        return _Tables()


def _ipc(table) -> bytes:
    import pyarrow as pa

    sink = pa.BufferOutputStream()
    with pa.ipc.new_stream(sink, table.schema) as w:
        w.write_table(table)
    return sink.getvalue().to_pybytes()


def _unipc(data: bytes):
    import pyarrow as pa

    return pa.ipc.open_stream(pa.py_buffer(data)).read_all()


class _Tables(Sink):
    """TableSink's rows of a part, as two Arrow tables and the points of each frame."""

    def __init__(self) -> None:
        from sniffer.formats.tables import TableSink, arrow_pool, schemas, to_batch

        class Collect(TableSink):
            def __init__(self) -> None:
                super().__init__()
                self.batches: tuple[list, list] = ([], [])
                self.schemas, self.pool = schemas(), arrow_pool()

            def _put(self, table: int, rows: list) -> None:
                self.batches[table].append(to_batch(rows, self.schemas[table], self.pool))

        self.sink = Collect()
        self.counts = array("I")

    def start(self, info) -> None:
        self.sink.start(info)

    def frame(self, f) -> None:
        self.counts.append(len(f.points))
        self.sink.frame(f)

    def close(self) -> None:
        self.sink.close()

    def piece(self):
        import pyarrow as pa

        tables = [pa.Table.from_batches(b, schema=s) for b, s in zip(self.sink.batches, self.sink.schemas)]
        return _ipc(tables[0]), _ipc(tables[1]), self.counts.tobytes()


class ParquetWriter:
    """The parts' rows cut into the record batches one process makes, into its row group files."""

    def __init__(self, file_sink) -> None:
        import pyarrow as pa

        from sniffer.formats.parquet import RowGroupFile
        from sniffer.formats.tables import CONVERT, schemas

        self.outputs = file_sink.outputs
        self.convert = CONVERT
        self.schemas = schemas()
        self.files: list = []
        self.carry = [None, None]  # rows not in a batch yet (a Table), per file
        self._row_group_file, self._pool = RowGroupFile, pa.system_memory_pool()

    def begin(self, info) -> None:
        for o, schema in zip(self.outputs, self.schemas):
            self.files.append(self._row_group_file(o.part, schema, self._pool))

    def _table(self, k: int, more):
        import pyarrow as pa

        carry = self.carry[k]
        return more if carry is None else pa.concat_tables([carry, more])

    def _put(self, k: int, table) -> None:
        for batch in table.combine_chunks().to_batches():
            self.files[k].put(batch)

    def add(self, piece) -> None:
        frames, points, counts = _unipc(piece[0]), _unipc(piece[1]), array("I", piece[2])
        n = self.convert
        t = self._table(0, frames)
        at = 0
        while t.num_rows - at >= n:
            self._put(0, t.slice(at, n))
            at += n
        self.carry[0] = t.slice(at)
        t = self._table(1, points)
        at, held = 0, self.carry[1].num_rows if self.carry[1] is not None else 0
        for c in counts:  # a batch of points ends after the frame that brings it to CONVERT rows
            held += c
            if held >= n:
                self._put(1, t.slice(at, held))
                at += held
                held = 0
        self.carry[1] = t.slice(at)

    def close(self) -> None:
        first = None
        for k, f in enumerate(self.files):
            try:
                if self.carry[k] is not None and self.carry[k].num_rows:
                    self._put(k, self.carry[k])
            except Exception as e:  # noqa: BLE001 - raised below, after every file is closed
                first = first or e
            finally:
                try:
                    f.close()
                except Exception as e:  # noqa: BLE001
                    first = first or e
        if first is not None:
            raise first
