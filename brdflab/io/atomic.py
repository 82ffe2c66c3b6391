"""Atomic saves: every file brdflab writes goes through here.

One exception to the rename below: a journal (`append_line`), which grows a line at a time
while long work runs; its reader skips a torn last line.

A unique temporary file in the target folder is written, fsync'ed and renamed over the
target (os.replace), so a crash, a full disk or a second writer never leaves a half-written
or unreadable file: readers see the old file or the new one. A target that is a symbolic
link is written through: the linked file is replaced, the link stays. A target that exists
and is not a regular file (a device such as /dev/full, a FIFO, a folder) is refused: a
rename would replace the node itself. Problems with the target (missing folder, read-only
folder, a file where the folder should be, a full disk) become one-line BRDFLabErrors that
name the file.
"""

from __future__ import annotations

import errno
import fcntl
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from brdflab.errors import BRDFLabError
from brdflab.io.bounded import kind_problem


def _problem(error: OSError, path: Path) -> str:
    """What went wrong, in the user's terms, with the system's own words after it."""
    folder = path.parent if str(path.parent) else Path(".")
    said = {errno.ENOENT: f"the folder {folder} does not exist",
            errno.ENOTDIR: f"a part of {folder} is a file, not a folder",
            errno.EACCES: f"the folder {folder} is read-only (no permission to create files there)",
            errno.EPERM: f"the folder {folder} is read-only (no permission to create files there)",
            errno.EROFS: f"the folder {folder} is on a read-only file system",
            errno.ENOSPC: "the disk is full", errno.EDQUOT: "the disk quota is exhausted",
            errno.EISDIR: "it is a folder"}.get(error.errno)
    system = error.strerror or str(error)
    return f"cannot write: {said} ({system})" if said else f"cannot write: {system}"


def _new_file_mode(path: Path) -> int:
    """Keep an existing file's permissions; a new file gets the usual ones (mkstemp's are private)."""
    try:
        return path.stat().st_mode & 0o7777
    except OSError:
        return 0o666 & ~_umask()


def _umask() -> int:
    """The process's umask, read without changing it where Linux tells it (setting and
    restoring it would race with other threads creating files)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    umask = os.umask(0o022)
    os.umask(umask)
    return umask


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """A unique temporary path in `path`'s folder for a writer that needs a file name
    (OpenEXR, savefig); when the block ends it is fsync'ed and renamed to `path`.
    On any error the temporary file is removed and the target is left as it was."""
    named = Path(path)
    path = write_target(named)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=path.parent)
    except OSError as e:
        raise BRDFLabError(_problem(e, path), named) from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.chmod(tmp, _new_file_mode(path))
        os.replace(tmp, path)
    except BaseException as e:
        tmp.unlink(missing_ok=True)
        if isinstance(e, OSError):
            raise BRDFLabError(_problem(e, path), named) from None
        raise


def write_target(path: Path) -> Path:
    """The file a save to `path` replaces: the file a symbolic link leads to (so the link
    keeps working and the linked file is updated), never something that is not a regular file."""
    target = Path(os.path.realpath(path)) if os.path.islink(path) else path
    try:
        mode = os.stat(target).st_mode
    except OSError:  # nothing there yet (or an unreadable folder: the write says so)
        return target
    problem = kind_problem(mode)
    if problem == "not a regular file: a directory":
        raise BRDFLabError("cannot write: it is a folder", path)
    if problem:
        raise BRDFLabError(f"cannot write: {problem}; only regular files are saved over", path)
    return target


def atomic_write(path: str | os.PathLike, data: bytes) -> None:
    """Write `data` to `path` atomically (see the module's docstring)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def append_line(path: str | os.PathLike, line: str) -> None:
    """Append one line (newline added) to a journal file, flushed to the disk at once, so that
    a killed run loses only the line it was writing."""
    path = Path(path)
    try:
        with path.open("a", encoding="utf-8") as f:
            f.write(line + "\n")
            f.flush()
            os.fsync(f.fileno())
    except OSError as e:
        raise BRDFLabError(f"{path}: {_problem(e, path)}") from None


def check_writable(path: str | os.PathLike) -> None:
    """Fail now, in one line, if `path` could not be saved later (before a long computation):
    its folder must exist, be a folder and take a new file."""
    try:
        with atomic_path(path):
            raise _Probe
    except _Probe:
        pass


class _Probe(Exception):
    """Ends a probing atomic_path block without saving anything."""


def ensure_folder(folder: str | os.PathLike) -> Path:
    """Create `folder` (and its parents) if needed and check that files can be saved in it."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise BRDFLabError("cannot write: it is a file, not a folder", folder) from None
    except OSError as e:
        raise BRDFLabError(_problem(e, folder), folder) from None
    check_writable(folder / ".brdflab-probe")
    return folder


@contextmanager
def folder_lock(folder: str | os.PathLike) -> Iterator[None]:
    """Hold an exclusive lock on `folder` (a `.brdflab.lock` file in it) while the block runs,
    so that processes that read, merge and rewrite the same files there take turns."""
    path = Path(folder) / ".brdflab.lock"
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
    except OSError as e:
        raise BRDFLabError(_problem(e, path), path) from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock
