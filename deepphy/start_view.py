"""What a run is doing before its progress line begins: the phase (checking the run,
starting Ray, starting workers), said at once and then again with the time it has taken,
every second on a terminal and every 10 s in a log.

Stdlib only: `deepphy run` starts it before its first heavy import, so its first line
comes within Python's own start. The repeats come from a small helper process: the run's
own process spends seconds inside C code that holds Python's GIL (Ray's start: 28 s of
silence on a loaded machine), where no thread of it can print. The helper reads the phase
from a pipe and ends when the pipe closes, so it dies with the run however the run ends.
"""

from __future__ import annotations

import sys
import time

# Seconds between a view's lines on a terminal and in a log (a file, CI): the start view's
# repeats; LOG_S for every view's lines in a log (a run's, a suite's, its cells').
TTY_S, LOG_S = 1.0, 10.0

# The helper (`python -I -S -c`): repeats the newest phase every INTERVAL seconds to its stdout.
# A message is one line "SINCE PHASE" (SINCE: time.monotonic() when the phase began, the same
# clock in both processes); end of input: clear the line (on a terminal) and exit.
_HELPER = r"""
import os, select, signal, sys, time
signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is for the run, which then closes the pipe
interval, tty = float(sys.argv[1]), sys.argv[2] == "1"
phase, since, pending, shown = "", 0.0, b"", False
due = None
while True:
    wait = None if due is None else max(0.0, due - time.monotonic())
    if select.select([0], [], [], wait)[0]:
        data = os.read(0, 65536)
        if not data:
            break
        *lines, pending = (pending + data).split(b"\n")
        for line in lines:
            start, _, text = line.decode(errors="replace").partition(" ")
            phase, since = text, float(start)
            due = since + interval
        continue
    took = int(time.monotonic() - since)
    os.write(1, (("\r\x1b[2K" if tty else "") + f"{phase} ... {took}s" + ("" if tty else "\n")).encode())
    shown, due = True, time.monotonic() + interval
if tty and shown:
    os.write(1, b"\r\x1b[2K")
"""


class StartView:
    """`say(phase)` prints `phase ...` at once (`at_once=False`: only as its first repeat,
    for a phase that is usually over in a blink); once `repeat()` has started the helper, it
    repeats the phase with the time it has taken; `stop()` ends the repeats (and clears the
    line on a terminal). A stream without a file descriptor (a test's StringIO) gets the
    phases, without repeats."""

    def __init__(self, stream, interval: float | None = None) -> None:
        self.stream = stream
        try:
            self.tty, self._fd = stream.isatty(), stream.fileno()
        except (AttributeError, OSError, ValueError):
            self.tty, self._fd = False, None
        self.interval = interval or (TTY_S if self.tty else LOG_S)
        self.said = False
        self._phase, self._since = "", 0.0  # the phase as last said (on a terminal line of its own), and since when
        self._helper = None
        self._stopped = False

    def say(self, phase: str, at_once: bool = True) -> None:
        self._phase, self._since = f"{phase} ...", time.monotonic()
        if at_once:
            self._write(("\r\x1b[2K" if self.tty else "") + self._phase + ("" if self.tty else "\n"))
        self._tell()

    def repeat(self) -> None:
        """Start the repeats (a command does once its arguments are known to be good: a bad
        flag's error waits for no process)."""
        if self._helper is not None or self._fd is None or self._stopped:
            return
        import subprocess  # only once the arguments are good: a bad flag's error waits for nothing

        try:
            self._helper = subprocess.Popen(
                [sys.executable, "-I", "-S", "-c", _HELPER, str(self.interval), "1" if self.tty else "0"],
                stdin=subprocess.PIPE, stdout=self._fd, stderr=subprocess.DEVNULL, close_fds=True)
        except OSError:  # no process to spare: the phases are still said
            self._stopped = True
            return
        self._tell()

    def _tell(self) -> None:
        if self._helper is None or not self._phase:
            return
        try:
            self._helper.stdin.write(f"{self._since!r} {self._phase.removesuffix(' ...')}\n".encode())
            self._helper.stdin.flush()
        except (OSError, ValueError):  # the helper is gone: no repeats
            self._helper, self._stopped = None, True

    def line(self, text: str) -> None:
        """A line of its own (on a terminal: above the phase's, which is shown again)."""
        self._write(f"\r\x1b[2K{text}\n{self._phase}" if self.tty and self.said else f"{text}\n")

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
            self.said = True
        except (OSError, ValueError):  # a closed stream: the view is best effort
            pass

    def stop(self) -> None:
        """End the repeats; the line is cleared on a terminal. Safe to call twice."""
        helper, self._helper, self._stopped = self._helper, None, True
        if helper is not None:
            try:
                helper.stdin.close()
                helper.wait(timeout=5)
            except Exception:  # noqa: BLE001 - a stuck helper must not hold the run
                helper.kill()
        if self.tty and self.said:
            self._write("\r\x1b[2K")
            self.said = False
