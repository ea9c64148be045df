"""``ucontrol`` commands run as children of a test, bounded in time and never left behind.

A child runs in a process group of its own (``start_new_session``) with SIGINT at its default
action even when pytest runs with SIGINT ignored (a background job), so that Ctrl-C reaches
it; its output is read by threads and waited for with deadlines; :meth:`Child.stop` kills its
group when it does not end, and a meshcat server it started ends with it (the server watches
the pipe from its parent).
"""

from __future__ import annotations

import queue
import re
import signal
import subprocess
import threading
import time

from conftest import sigint_default

from ucontrol.viz.browser_screenshot import kill_group

#: Longest wait for an expected line of output, in [s].
LINE_TIMEOUT = 120.0
#: Longest wait for a child to end after Ctrl-C, in [s].
EXIT_TIMEOUT = 60.0


class Child:
    """A command running in its own process group, its output collected line by line.

    Args:
        command: Program and arguments.
    """

    def __init__(self, command: list[str]) -> None:
        with sigint_default():
            self.process = subprocess.Popen(
                command,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
                start_new_session=True,
            )
        self._lines: queue.Queue[str | None] = queue.Queue()
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        self._readers = [
            threading.Thread(target=self._read_stdout, daemon=True),
            threading.Thread(target=self._read_stderr, daemon=True),
        ]
        for reader in self._readers:
            reader.start()

    def _read_stdout(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.stdout.append(line)
            self._lines.put(line)
        self._lines.put(None)

    def _read_stderr(self) -> None:
        assert self.process.stderr is not None
        for line in self.process.stderr:
            self.stderr.append(line)

    def wait_for(self, pattern: str, timeout: float = LINE_TIMEOUT) -> str:
        """The first line of standard output (not yet returned) that holds ``pattern``.

        Raises:
            AssertionError: The output ended, or no such line came within ``timeout`` [s].
        """
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            try:
                line = self._lines.get(timeout=max(remaining, 0.0))
            except queue.Empty:
                raise AssertionError(
                    f"no {pattern!r} line within {timeout:g} s; stderr: {''.join(self.stderr)}"
                ) from None
            if line is None:
                self.process.wait(timeout=EXIT_TIMEOUT)
                raise AssertionError(f"no {pattern!r} line; stderr: {''.join(self.stderr)}")
            if pattern in line:
                return line

    def url(self, pattern: str) -> str:
        """The viewer address printed on the line with ``pattern``."""
        line = self.wait_for(pattern)
        match = re.search(r"http://\S+/static/", line)
        assert match is not None, line
        return match.group(0)

    def interrupt(self, timeout: float = EXIT_TIMEOUT) -> int | None:
        """Send Ctrl-C (SIGINT) and wait for the exit; the exit status, None when killed."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        try:
            status = self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.stop()
            return None
        self._join()
        return status

    def stop(self) -> None:
        """Kill the child's process group (a no-op once it has ended) and collect its output."""
        kill_group(self.process)
        self._join()

    def _join(self) -> None:
        for reader in self._readers:
            reader.join(timeout=EXIT_TIMEOUT)

    @property
    def output(self) -> str:
        """Standard output so far."""
        return "".join(self.stdout)
