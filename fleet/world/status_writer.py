"""Writing the world's status file from a second process.

Encoding a status of hundreds of robots (their trails and scan points as JSON) takes tens of
milliseconds, several times a second: done in the world's process it would come out of the
physics thread's time.  The world sends the status parts (fleet.world.status.finish_status
turns them into the document) pickled over a pipe to `python -m fleet.world.status_writer PATH`,
which finishes and writes each one and acknowledges it with one byte.  Only one status is in
flight: one due while the previous is still being written is skipped, the next one is current.
The pickled bytes go through the pipe from a thread of their own (a pipe takes 64 KiB at a time,
and writing to it releases the GIL), so the physics thread only pays for pickling.
"""

from __future__ import annotations

import contextlib
import pickle
import queue
import select
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

from fleet.lifetime import helper_of_parent
from fleet.world.status import finish_status, write_status


class StatusWriter:
    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._child = subprocess.Popen(
            [sys.executable, "-m", "fleet.world.status_writer", str(self.path)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            # Dead with the world even when the world is SIGKILLed: a writer still starting up
            # (slow under load) would otherwise outlive it until it reads the closed pipe.  Deaf to
            # Ctrl-C, which reaches the world's whole process group: the world stops, then closes the pipe.
            preexec_fn=helper_of_parent,
        )
        self._in_flight = False
        self._outgoing: queue.Queue[bytes | None] = queue.Queue()
        self._sender = threading.Thread(target=self._send, name="status-sender", daemon=True)
        self._sender.start()

    def _send(self) -> None:
        pipe = self._child.stdin
        assert pipe is not None
        with contextlib.suppress(BrokenPipeError, ValueError):  # the writer is gone / closed
            while (data := self._outgoing.get()) is not None:
                pipe.write(data)
                pipe.flush()

    def _acknowledged(self, timeout: float) -> bool:
        assert self._child.stdout is not None
        if self._in_flight and select.select([self._child.stdout], [], [], timeout)[0]:
            self._in_flight = not self._child.stdout.read(1)  # b"" (EOF): the writer is gone
        return not self._in_flight

    def submit(self, parts: dict[str, Any]) -> bool:
        """Hand a status over to be written; False (not sent) while the previous is being written."""
        if not self._acknowledged(0.0) or self._child.poll() is not None:
            return False
        self._outgoing.put(pickle.dumps(parts, protocol=pickle.HIGHEST_PROTOCOL))
        self._in_flight = True
        return True

    def settle(self, timeout: float = 5.0) -> None:
        """Wait until the status in flight (if any) is written."""
        self._acknowledged(timeout)

    def close(self, timeout: float = 5.0) -> None:
        """Let the status in flight be written, then end the writer."""
        self.settle(timeout)
        self._outgoing.put(None)
        self._sender.join(timeout)
        assert self._child.stdin is not None
        with contextlib.suppress(BrokenPipeError):
            self._child.stdin.close()
        try:
            self._child.wait(timeout)
        except subprocess.TimeoutExpired:
            self._child.kill()
            self._child.wait()


def main(path: str) -> None:
    source, ack = sys.stdin.buffer, sys.stdout.buffer
    while True:
        try:
            parts = pickle.load(source)
        except EOFError:  # the world closed the pipe (or ended): so does its writer
            return
        write_status(path, finish_status(parts))
        ack.write(b".")
        ack.flush()


if __name__ == "__main__":
    main(sys.argv[1])
