"""Writing outputs so that nothing is lost: locations checked first, atomic files, run locks.

Every command that writes checks its output location before any work starts
(:func:`check_output_dir`, :func:`check_output_file`). Files are written under a unique
temporary name in their own directory, flushed to disk and renamed over the target
(:func:`write_atomically`): a reader sees the previous complete file or the new one, never a
mix; a failed write (a full disk) removes its temporary file and keeps the previous one. A run
holds its output directory with a lock file naming its process (:class:`OutputLock`).
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

from ucontrol.exceptions import OutputInUseError, OutputPathError, OutputWriteError

#: Name of the lock file a run keeps in its output directory while it runs.
LOCK_FILE = ".ucontrol.lock"


def _as_path(name: str, path: Any) -> Path:
    if not isinstance(path, str | os.PathLike):
        raise OutputPathError(name, repr(path), "a path is a string or os.PathLike")
    return Path(path)


def check_output_dir(name: str, path: Any) -> Path:
    """``path`` as a directory that exists (created if needed) and can be written.

    Raises:
        OutputPathError: ``path`` is not a path, names a file or a device, cannot be created,
            or is not writable.
    """
    directory = _as_path(name, path)
    if directory.exists() and not directory.is_dir():
        raise OutputPathError(name, str(directory), "it is a file, not a directory")
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OutputPathError(name, str(directory), error.strerror or str(error)) from error
    if not os.access(directory, os.W_OK | os.X_OK):
        raise OutputPathError(name, str(directory), "the directory is not writable")
    return directory


def check_output_file(name: str, path: Any) -> Path:
    """``path`` as a regular file that can be (re)written: its folder is created if needed.

    Raises:
        OutputPathError: ``path`` is not a path, names a directory or a device, or its folder
            cannot be created or written.
    """
    file = _as_path(name, path)
    if file.exists() and not file.is_file():
        kind = "a directory" if file.is_dir() else "not a regular file"
        raise OutputPathError(name, str(file), f"it is {kind}")
    check_output_dir(name, file.parent)
    return file


def write_atomically(path: str | os.PathLike[str], write: Callable[[IO[bytes]], None]) -> Path:
    """Write a file through ``write(stream)`` under a temporary name, then rename it over ``path``.

    Raises:
        OutputWriteError: The write failed (e.g. no space left); ``path`` is left as it was
            and the temporary file is removed.
    """
    target = Path(path)
    descriptor, temporary = tempfile.mkstemp(
        prefix=f".{target.name}.", suffix=".tmp", dir=target.parent
    )
    try:
        with os.fdopen(descriptor, "wb") as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, target)
    except OSError as error:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise OutputWriteError(str(target), error.strerror or str(error)) from error
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise
    return target


class OutputLock:
    """Exclusive use of an output directory by one process, through a lock file.

    A lock left by a process that no longer runs is taken over.

    Args:
        directory: The output directory (it must exist).
    """

    def __init__(self, directory: Path) -> None:
        self.path = Path(directory) / LOCK_FILE
        self._held = False

    def acquire(self) -> None:
        """Take the lock.

        Raises:
            OutputInUseError: A running process holds it.
        """
        for _ in range(3):  # a stale lock is removed, then created again
            if self._create():
                self._held = True
                return
            owner = _owner(self.path)
            if owner is not None and owner != os.getpid() and _alive(owner):
                raise OutputInUseError(str(self.path.parent), owner) from None
            if _owner(self.path) == owner:  # still the stale one: take it over
                with contextlib.suppress(FileNotFoundError):
                    self.path.unlink()
        raise OutputInUseError(str(self.path.parent), _owner(self.path) or -1)

    def _create(self) -> bool:
        """Create the lock file with this process's id in one step; False if it exists.

        The id is written to a temporary file first and linked to the lock's name, so that
        another process never reads a lock file without its owner.
        """
        descriptor, temporary = tempfile.mkstemp(prefix=".lock.", dir=self.path.parent)
        try:
            with os.fdopen(descriptor, "w") as stream:
                stream.write(str(os.getpid()))
            os.link(temporary, self.path)
        except FileExistsError:
            return False
        finally:
            os.unlink(temporary)
        return True

    def release(self) -> None:
        """Give the lock back (only if this process holds it)."""
        if self._held and _owner(self.path) == os.getpid():
            with contextlib.suppress(FileNotFoundError):
                self.path.unlink()
        self._held = False

    @contextlib.contextmanager
    def held(self) -> Iterator[OutputLock]:
        """Hold the lock within a ``with`` block."""
        self.acquire()
        try:
            yield self
        finally:
            self.release()


#: Largest process id of Linux (``pid_max`` cannot exceed it); larger ids are not processes.
_PID_MAX = 2**22


def _owner(path: Path) -> int | None:
    """The process id in the lock file, or None when it holds no possible process id."""
    try:
        pid = int(path.read_text().strip())
    except (OSError, ValueError):
        return None
    return pid if 0 < pid <= _PID_MAX else None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by another user
        return True
    except OSError as error:
        return error.errno != errno.ESRCH
    return True
