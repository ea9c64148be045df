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
- Definitions: a library may also be recorded under a *definition key*, what its Function is
  built from (:func:`definition_key`: the inputs of the code that writes the Function, the
  sources of that code, casadi's installed files), as a second name (a hard link) of the
  same file. A later process finds it by that key (:func:`find_library`) without building
  the Function, so without importing casadi: it loads the library and reads the Function's
  signature from it (``ucontrol.model.compiled_function``). A miss builds the Function as
  before.
- Background: a large program's library (minutes of ``gcc``) may be built by a detached,
  niced process (``build_library(..., background=True)``): the caller goes on without it,
  the process holds the entry's lock while it compiles (a second caller finds it held and
  neither waits nor builds), and renames the library into place when done. A failed build
  removes its work directory and its lock file and leaves a marker, ``<library>.failed``
  (the compiler's last words): later callers do not start the same build again, which would
  fail again after minutes of the compiler (out of memory, say), until the marker is
  removed (:func:`failure_marker`). Another compiler or flags name another library.
- Size: at most :data:`MAX_LIBRARIES` libraries, the least recently used removed after a build
  (a library's modification time is its last use: each lookup that finds it touches it). A
  process that has loaded a removed library keeps it; a later lookup builds it again.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import importlib.util
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Literal, overload

#: C source, or a callable returning it.
Source = str | Callable[[], str]
#: Compiler flags.
Flags = tuple[str, ...]
#: Overrides the cache directory.
CACHE_ENV = "UCONTROL_CACHE_DIR"
#: Compiler flags (optimisation level chosen for build time: the laws are a few thousand lines).
CFLAGS = ("-O1", "-fPIC", "-shared")
#: Seconds a build may take before it is abandoned for the fallback.
BUILD_TIMEOUT_S = 300.0
#: Seconds a background build may take before it is abandoned (the Panda's design: ~11 min).
BACKGROUND_TIMEOUT_S = 3600.0
#: Niceness added to a background build (the compiler runs behind the user's work).
BACKGROUND_NICENESS = 10
#: Libraries kept in the cache; a build beyond them removes the least recently used.
MAX_LIBRARIES = 256
#: What a build compiles, by default (said on the terminal).
_LAWS = "this scene's laws (first run only; later runs load them)"
#: The background builds this process started (:func:`wait_for_builds`).
_builds: list[subprocess.Popen[bytes]] = []
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


@overload
def build_library(
    stem: str,
    key: str,
    source: Source,
    flags: tuple[str, ...] = ...,
    *,
    notice: str = ...,
    background: Literal[False] = ...,
) -> Path: ...


@overload
def build_library(
    stem: str, key: str, source: Source, flags: Flags = ..., *, background: bool, notice: str = ...
) -> Path | None: ...


def build_library(
    stem: str,
    key: str,
    source: Source,
    flags: tuple[str, ...] = (),
    *,
    notice: str = _LAWS,
    background: bool = False,
) -> Path | None:
    """Path of the shared library compiled from C ``source``, built (once) into the cache.

    Args:
        stem: Start of the library's file name.
        key: What the library depends on besides the compiler command (hashed into the name).
        source: The C source, or a callable returning it (called only to build).
        flags: Compiler flags after :data:`CFLAGS`.
        notice: What is compiled, and how long it may take, said on the terminal before the
            process's first build (with ``background``: said on every start of a build).
        background: Where the library is not built yet, write the source and compile it in a
            detached process niced by :data:`BACKGROUND_NICENESS` (:func:`wait_for_builds`
            waits for it), and return None at once; None too while another process builds
            it.

    Returns:
        The library's path; None with ``background`` where it is not built yet.

    Raises:
        OSError: No C compiler.
        subprocess.SubprocessError: The compilation failed or timed out (not in the
            background: a failed background build leaves no library and no lock file).
    """
    library = library_path(stem, key, flags)
    directory = library.parent
    directory.mkdir(parents=True, exist_ok=True)
    if _touch(library):
        return library
    if background and failure_marker(library).exists():  # failed before: not again
        if sys.stderr.isatty():
            print(
                f"ucontrol: {notice} not compiled: an earlier build failed "
                f"({failure_marker(library)}; remove it to try again)",
                file=sys.stderr,
            )
        return None
    with open(directory / f"{library.name}.lock", "w") as lock:
        try:
            # one builder; in the foreground the others wait, then find it built
            fcntl.flock(lock, fcntl.LOCK_EX | (fcntl.LOCK_NB if background else 0))
        except BlockingIOError:  # built in the background by another process meanwhile
            return None
        if _touch(library):
            return library
        built = Path(tempfile.mkdtemp(dir=directory))
        work: Path | None = built  # removed here unless a background build owns it
        command = [*compiler_command(), *CFLAGS, *flags, "-o", str(built / library.name)]
        try:
            path = built / f"{stem}.c"
            path.write_text(source if isinstance(source, str) else source())
            command += [str(path), "-lm"]
            if background:
                _start_background_build(command, library, lock.fileno(), notice)
                work = None  # the build's own: it removes it
                return None
            _announce(directory, notice)
            _compile(command, library, BUILD_TIMEOUT_S)
        finally:
            if work is not None:
                shutil.rmtree(work, ignore_errors=True)
    return library


def _compile(command: list[str], library: Path, timeout: float) -> None:
    """Run the compiler ``command`` (its output last), then rename its output to ``library``.

    Raises:
        subprocess.SubprocessError: The compilation failed or timed out.
    """
    subprocess.run(command, check=True, capture_output=True, timeout=timeout)
    os.replace(command[command.index("-o") + 1], library)  # atomic: no partial library seen
    _remove_least_recently_used(library.parent, library)


def _start_background_build(command: list[str], library: Path, lock: int, notice: str) -> None:
    """Compile in a detached process that inherits (and so holds) the ``lock`` descriptor.

    The process outlives its caller (its own session: a terminal's interrupt spares it). It
    is recorded for :func:`wait_for_builds`.
    """
    child = subprocess.Popen(
        [sys.executable, "-m", __name__, str(library), str(lock), *command],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        pass_fds=(lock,),
        start_new_session=True,
    )
    _builds.append(child)
    if sys.stderr.isatty():
        print(
            f"ucontrol: compiling {notice} in the background (pid {child.pid}) into "
            f"{library.parent}",
            file=sys.stderr,
        )


def failure_marker(library: Path) -> Path:
    """The file a failed background build of ``library`` leaves: remove it to try again."""
    return library.with_name(f"{library.name}.failed")


def wait_for_builds(timeout: float) -> list[int]:
    """Wait for the background builds this process started; their exit codes (0: built).

    Args:
        timeout: Seconds to wait for each [s].

    Raises:
        subprocess.TimeoutExpired: A build runs longer than ``timeout``.
    """
    codes = [child.wait(timeout) for child in _builds]
    _builds.clear()
    return codes


def _background_main(arguments: list[str]) -> int:
    """A background build (``python -m ucontrol.model.compile_cache LIBRARY LOCK CC ...``).

    Holds the lock descriptor it inherited until it exits; compiles niced, renames the
    library into place; on failure writes the :func:`failure_marker` (the compiler's last
    output) and removes the lock file. In every case removes the compiler's work directory.
    """
    library, lock, command = Path(arguments[0]), int(arguments[1]), arguments[2:]
    os.nice(BACKGROUND_NICENESS)
    try:
        _compile(command, library, BACKGROUND_TIMEOUT_S)
    except (OSError, subprocess.SubprocessError) as error:
        said = getattr(error, "stderr", None) or b""
        reason = f"{error}\n{said.decode(errors='replace')[-2000:]}"
        failure_marker(library).write_text(reason)
        Path(f"{library}.lock").unlink(missing_ok=True)  # still held: no one builds meanwhile
        return 1
    finally:
        shutil.rmtree(Path(command[command.index("-o") + 1]).parent, ignore_errors=True)
        os.close(lock)
    return 0


def library_path(stem: str, key: str, flags: tuple[str, ...] = ()) -> Path:
    """Where the library of ``stem`` and ``key`` compiled with ``flags`` is (or would be) cached.

    Raises:
        OSError: No C compiler.
    """
    compiler = compiler_command()
    digest = hashlib.sha256((key + " ".join([*compiler, *CFLAGS, *flags])).encode()).hexdigest()
    return cache_dir() / f"{stem}_{digest[:24]}.so"


def definition_key(parts: Iterable[object], modules: Iterable[str]) -> str:
    """A definition key: ``parts`` (their reprs), the sources of ``modules`` and casadi's files.

    Args:
        parts: What the Function is built from besides code (sizes, options, a robot model's
            serialized form); each part's ``repr`` is hashed, so floats are exact.
        modules: The modules whose code writes the Function (their source files are hashed,
            read without importing them).

    The installed casadi is named by its extension module's path, size and modification time
    (a reinstall changes them), read without importing casadi. Both are read once per process
    (the code a process runs is the code it loaded).

    Raises:
        OSError: A module's or casadi's file cannot be found or read.
    """
    digest = hashlib.sha256()
    for part in parts:
        digest.update(repr(part).encode() + b"\0")
    for module in modules:
        digest.update(_source_digest(module))
    digest.update(_casadi_files())
    return "definition:" + digest.hexdigest()


@functools.cache
def _source_digest(module: str) -> bytes:
    """SHA-256 of ``module``'s source file, read once per process without importing it.

    Raises:
        OSError: The module has no source file.
    """
    spec = importlib.util.find_spec(module)  # (imports its package, not the module)
    if spec is None or spec.origin is None:
        raise OSError(f"no source file for module {module}")
    return hashlib.sha256(Path(spec.origin).read_bytes()).digest()


@functools.cache
def _casadi_files() -> bytes:
    """The installed casadi's extension module: path, size and modification time (once).

    Raises:
        OSError: casadi or its extension module is missing.
    """
    spec = importlib.util.find_spec("casadi")
    if spec is None or not spec.submodule_search_locations:
        raise OSError("casadi is not installed")
    core = next(Path(spec.submodule_search_locations[0]).glob("_casadi*"), None)
    if core is None:
        raise OSError("casadi's extension module is missing")
    info = core.stat()
    return f"{core}:{info.st_size}:{info.st_mtime_ns}".encode()


def find_library(stem: str, key: str) -> Path | None:
    """The cached library recorded under ``key`` (:func:`record_library`), or None.

    A library found has its use recorded (as in :func:`build_library`). None also without a C
    compiler (nothing compiled can be used then).
    """
    try:
        library = library_path(stem, key)
    except OSError:
        return None
    return library if _touch(library) else None


def record_library(stem: str, key: str, library: Path) -> None:
    """Record the cached ``library`` under ``key`` too, for :func:`find_library`.

    A second name of the same file (a hard link, made atomically); where the file system has
    no hard links, nothing is recorded and later lookups by ``key`` miss.
    """
    # An existing name was recorded by another process meanwhile (the same definition).
    with contextlib.suppress(OSError):
        os.link(library, library_path(stem, key))


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


def _announce(directory: Path, notice: str) -> None:
    """Say once per process, on a terminal, that compiled code is being built into the cache."""
    global _announced
    if _announced or not sys.stderr.isatty():
        return
    _announced = True
    print(
        f"ucontrol: compiling {notice} into {directory}",
        file=sys.stderr,
    )


if __name__ == "__main__":
    sys.exit(_background_main(sys.argv[1:]))
