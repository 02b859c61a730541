"""Writing output files so that a failure never leaves a half-written file behind.

Rules (issue #20): an output is never one of the inputs (same inode, whatever the name or
link); a symlink is written through to its target, which stays a link; anything that is not
a regular file (a device node, a folder, a FIFO) is refused; SIGTERM during the write cleans
up like Ctrl-C; and :func:`check_output` lets a caller refuse an unwritable location before a
long computation rather than after it.

SIGKILL (or a power cut) leaves the temporary file behind: nothing can clean up in the dying
process. Temporary names carry this machine's name and the writing process's id, so the next
write into the same folder removes those of this machine whose process no longer runs (once
per folder and process; another machine's, on a shared disk, are left alone).
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import socket
import stat
import tempfile
import threading
from pathlib import Path

from csgs_codec.errors import InputError

PathLike = str | os.PathLike

#: This machine's name as temporary file names carry it (letters, digits, '_'; 16 at most).
_HOST = re.sub(r"[^A-Za-z0-9_]", "_", socket.gethostname())[:16] or "host"
#: A temporary file's name: '.<target>.<host>-<pid>.<random>.tmp' (tempfile's random part).
_TEMPORARY = re.compile(r"\..+\.([A-Za-z0-9_]{1,16})-([0-9]{1,10})\.[a-z0-9_]+\.tmp")
#: Folders whose stale temporary files this process has removed already.
_swept: set[str] = set()


def check_output(path: PathLike, inputs: tuple[PathLike, ...] | list[PathLike] = ()) -> Path:
    """The file an output named ``path`` is written to, after checking it may be written.

    Symlinks are followed (the data goes to their target). Nothing is created.

    Raises:
        InputError: naming ``path`` when the target is not a regular file, is the same file
            as one of ``inputs``, or its folder is missing or not writable.
    """
    target = Path(os.path.realpath(path))
    try:
        info = os.stat(target)
    except FileNotFoundError:
        info = None
    except OSError as exc:
        raise InputError(f"cannot write here: {exc.strerror or exc}", file=path) from None
    if info is not None:
        if not stat.S_ISREG(info.st_mode):
            raise InputError("is not a regular file; refusing to replace it", file=path)
        for source in inputs:
            with contextlib.suppress(OSError):
                if os.path.samefile(source, target):
                    raise InputError(f"is the input file {os.fspath(source)!r}; refusing to "
                                     "overwrite it (choose another output)", file=path)
    folder = target.parent
    if not folder.is_dir():
        raise InputError(f"cannot write here: folder {str(folder)!r} does not exist", file=path)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"cannot write here: folder {str(folder)!r} is not writable",
                         file=path)
    return target


def write_atomically(path: PathLike, data: bytes,
                     inputs: tuple[PathLike, ...] | list[PathLike] = ()) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename.

    A symlink ``path`` is written through: its target is replaced and the link kept. The
    temporary file is flushed to disk before the rename. A file it replaces passes on its
    mode, and its owner and group where this process may set them (silently kept as they
    come otherwise); a new file gets the ordinary mode (0666 less the umask). On any
    failure, Ctrl-C or SIGTERM the temporary file is removed and ``path`` is left as it was.

    Raises:
        InputError: naming ``path`` when the folder is missing or not writable, the target is
            not a regular file, or it is one of ``inputs`` (see :func:`check_output`).
    """
    target = check_output(path, inputs)
    replaced = _existing(target)
    remove_stale_temporaries(target.parent)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.{_HOST}-{os.getpid()}.",
                                   suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise InputError(f"cannot write here: {exc.strerror or exc}", file=path) from None
    try:
        with sigterm_as_interrupt():
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
            _take_mode(tmp, replaced)
            os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise InputError(f"cannot write: {exc.strerror or exc}", file=path) from None
        raise


def remove_stale_temporaries(folder: PathLike) -> list[str]:
    """Remove the temporary files :func:`write_atomically` left in ``folder`` when its
    process was killed (SIGKILL leaves them): those of this machine whose process id no
    longer runs. Looks at a folder once per process; returns the names removed.

    Files of a running process, of another machine, or not named as temporaries are left
    alone, and a file that cannot be removed is skipped silently.
    """
    key = os.path.realpath(folder)
    if key in _swept:
        return []
    _swept.add(key)
    removed = []
    with contextlib.suppress(OSError), os.scandir(key) as entries:
        for entry in entries:
            match = _TEMPORARY.fullmatch(entry.name)
            if match is None or match[1] != _HOST or _running(int(match[2])):
                continue
            with contextlib.suppress(OSError):
                os.unlink(entry.path)
                removed.append(entry.name)
    return removed


def _running(pid: int) -> bool:
    """Whether a process ``pid`` exists on this machine (one of another user counts)."""
    if pid == os.getpid() or os.name == "nt":  # Windows' os.kill(pid, 0) would end it
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, OSError):
        return True
    return True


@contextlib.contextmanager
def sigterm_as_interrupt():
    """A context manager: within it SIGTERM raises KeyboardInterrupt, so cleanup runs as
    for Ctrl-C; the previous handler is restored after. Only the main thread can set
    handlers: elsewhere it changes nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt(f"signal {signum}")

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _existing(target: Path) -> os.stat_result | None:
    """The status of the file ``target`` names, or None when there is none yet."""
    try:
        return os.stat(target)
    except OSError:
        return None


def _take_mode(tmp: str, replaced: os.stat_result | None) -> None:
    """Give the temporary file ``tmp`` the mode (and, where permitted, the owner and group)
    of the file it replaces, or the ordinary mode of a new file: mkstemp makes it 0600."""
    if replaced is None:
        os.chmod(tmp, 0o666 & ~_umask())
        return
    # Owner first: chown clears set-user/group-ID bits, which the chmod then restores.
    if hasattr(os, "chown"):
        with contextlib.suppress(OSError):
            os.chown(tmp, replaced.st_uid, -1)
        with contextlib.suppress(OSError):
            os.chown(tmp, -1, replaced.st_gid)
    os.chmod(tmp, stat.S_IMODE(replaced.st_mode))


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
