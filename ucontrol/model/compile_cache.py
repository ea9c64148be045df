"""The on-disk cache of shared libraries compiled from generated C: hashed, locked, atomic.

Shared by :mod:`ucontrol.model.compiled_function` (one library per casadi Function) and
:mod:`ucontrol.model.native_call` (the extension that calls them without ``ctypes``).

- Cache: ``$UCONTROL_CACHE_DIR`` or ``$XDG_CACHE_HOME/ucontrol`` or ``~/.cache/ucontrol``,
  sub-directory ``casadi``; each library is named by the SHA-256 of what it depends on (for a
  Function: its serialized form and the casadi version) and of the compiler command, so a
  changed source is rebuilt and an unchanged one never is.
- Notice: the first build of a process, when stderr is a terminal, says so once on it (a
  first run compiles its scene's laws, a fraction of a second to a few seconds; later runs
  load them).
- Concurrency: the build of an entry holds an exclusive ``fcntl`` lock on its lock file, and
  the library is written under a temporary name then renamed (atomic on POSIX): concurrent
  processes (tests, dask workers) build it once and never load a partial file.
- Size: at most :data:`MAX_LIBRARIES` libraries, the least recently used removed after a build
  (a library's modification time is its last use: each lookup that finds it touches it). A
  process that has loaded a removed library keeps it; a later lookup builds it again.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

#: Overrides the cache directory.
CACHE_ENV = "UCONTROL_CACHE_DIR"
#: Compiler flags (optimisation level chosen for build time: the laws are a few thousand lines).
CFLAGS = ("-O1", "-fPIC", "-shared")
#: Seconds a build may take before it is abandoned for the fallback.
BUILD_TIMEOUT_S = 300.0
#: Libraries kept in the cache; a build beyond them removes the least recently used.
MAX_LIBRARIES = 256
#: Whether this process has said on the terminal that it compiles (said once).
_announced = False


def cache_dir() -> Path:
    """Directory holding the compiled libraries."""
    root = os.environ.get(CACHE_ENV)
    if root:
        return Path(root) / "casadi"
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "ucontrol" / "casadi"


def compiler_command() -> list[str]:
    """The C compiler's command (``$CC``, default ``cc``), or an OSError if it is missing."""
    command = shlex.split(os.environ.get("CC", "cc"))
    if not command or shutil.which(command[0]) is None:
        raise OSError(f"no C compiler ({' '.join(command) or 'CC empty'})")
    return command


def build_library(
    stem: str, key: str, source: str | Callable[[], str], flags: tuple[str, ...] = ()
) -> Path:
    """Path of the shared library compiled from C ``source``, built (once) into the cache.

    Args:
        stem: Start of the library's file name.
        key: What the library depends on besides the compiler command (hashed into the name).
        source: The C source, or a callable returning it (called only to build).
        flags: Compiler flags after :data:`CFLAGS`.

    Raises:
        OSError: No C compiler.
        subprocess.SubprocessError: The compilation failed or timed out.
    """
    compiler = compiler_command()
    digest = hashlib.sha256((key + " ".join([*compiler, *CFLAGS, *flags])).encode()).hexdigest()[
        :24
    ]
    directory = cache_dir()
    directory.mkdir(parents=True, exist_ok=True)
    library = directory / f"{stem}_{digest}.so"
    if _touch(library):
        return library
    with open(directory / f"{library.name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # one builder; the others wait, then find it built
        if _touch(library):
            return library
        _announce(directory)
        with tempfile.TemporaryDirectory(dir=directory) as work:
            path = Path(work) / f"{stem}.c"
            path.write_text(source if isinstance(source, str) else source())
            target = Path(work) / library.name
            subprocess.run(
                [*compiler, *CFLAGS, *flags, "-o", str(target), str(path), "-lm"],
                check=True,
                capture_output=True,
                timeout=BUILD_TIMEOUT_S,
            )
            os.replace(target, library)  # atomic: readers see no partial library
    _remove_least_recently_used(directory, library)
    return library


def _touch(library: Path) -> bool:
    """Whether ``library`` exists; if so its modification time becomes now (its last use)."""
    try:
        os.utime(library)
    except FileNotFoundError:
        return False
    except OSError:  # a read-only cache: found, its use not recorded
        return library.is_file()
    return True


def _remove_least_recently_used(directory: Path, built: Path) -> None:
    """Remove the libraries (and their lock files) beyond :data:`MAX_LIBRARIES`, oldest first.

    ``built`` (the library just built) is never removed.
    """
    used: list[tuple[float, str]] = []
    with os.scandir(directory) as entries:
        for entry in entries:
            if entry.name.endswith(".so") and entry.name != built.name:
                try:
                    used.append((entry.stat().st_mtime, entry.name))
                except FileNotFoundError:  # removed meanwhile by another process
                    continue
    used.sort()
    for _, name in used[: max(0, len(used) + 1 - MAX_LIBRARIES)]:
        for path in (directory / name, directory / f"{name}.lock"):
            path.unlink(missing_ok=True)


def _announce(directory: Path) -> None:
    """Say once per process, on a terminal, that compiled code is being built into the cache."""
    global _announced
    if _announced or not sys.stderr.isatty():
        return
    _announced = True
    print(
        f"ucontrol: compiling this scene's laws into {directory} (first run only; later runs "
        "load them)",
        file=sys.stderr,
    )
