"""A worker process: decodes the parts the coordinator sends, one at a time (sniffer.parallel.part).

The conversation on the worker's pipe (each message one pickle):

    coordinator -> worker    ("setup", spec, info, plans)   once
                             ("part", Task)
    worker -> coordinator    ("counted", Counted)           the part decoded, its frames held
    coordinator -> worker    ("base", N)                    the part's first frame number: encode
                             ("drop",)                      the part was decoded from a wrong guess
    worker -> coordinator    ("pieces", part, [piece, ...]) one per plan
                             ("error", text)                a bug: the traceback's last line
    coordinator -> worker    ("stop",)

The worker ignores Ctrl-C (the coordinator ends it by its pipe or by terminate(); a
coordinator killed outright, by the kernel or a watcher: processes/parent_death.py)
and holds one part at a time, so its memory is one part's frames.
"""

from __future__ import annotations

import pickle
import signal
import traceback


def send(conn, msg) -> None:
    conn.send_bytes(pickle.dumps(msg, protocol=pickle.HIGHEST_PROTOCOL))


def recv(conn):
    return pickle.loads(conn.recv_bytes())


def serve(conn, parent_pid: int, from_main_thread: bool) -> None:
    """The worker's main loop (a multiprocessing.Process target); it ends with the coordinator's process even
    killed outright (processes/parent_death.py)."""
    from sniffer.parallel.events import NotIndexed
    from sniffer.parallel.part import Counted, run_part
    from sniffer.processes.parent_death import worker_ends_with_parent

    worker_ends_with_parent(parent_pid, from_main_thread)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    spec = info = plans = None
    try:
        while True:
            try:
                msg = recv(conn)
            except (EOFError, OSError):
                return
            kind = msg[0]
            if kind == "stop":
                return
            if kind == "setup":
                _, spec, info, plans = msg
                continue
            task = msg[1]
            try:
                result = run_part(spec, info, plans, task)
            except NotIndexed as e:  # the coordinator reads these events itself
                send(conn, ("counted", Counted(task.part, None, why=str(e))))
                continue
            send(conn, ("counted", result.counted))
            if result.counted.cut is None or result.counted.no_end:
                continue  # it holds nothing: the coordinator decodes the part itself
            answer = recv(conn)
            if answer[0] == "base":
                send(conn, ("pieces", task.part, result.pieces(answer[1])))
            elif answer[0] == "stop":
                return
    except Exception as e:  # noqa: BLE001 - a bug: the coordinator says it in one line, the traceback here
        traceback.print_exc()
        try:
            send(conn, ("error", f"a worker failed: {type(e).__name__}: {e}"))
        except OSError:
            pass
