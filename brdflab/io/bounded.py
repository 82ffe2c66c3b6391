"""Reading files a user names, in bounded time and memory.

Special files (FIFOs, devices, directories, sockets) are refused by their type: a FIFO
would block forever and /dev/zero never ends. Sizes are checked against what the format
allows before a byte is read, so a 20 GB sparse file costs one `fstat`. The file is opened
with O_NONBLOCK (opening a FIFO then returns at once) and checked on the open descriptor,
so a file swapped between the check and the read is still caught.
"""

from __future__ import annotations

import hashlib
import os
import stat
from pathlib import Path

from brdflab.errors import BRDFLabError

MAX_DATA_BYTES = 256 << 20  # any measured data file (a MERL table is 35 MB)

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def kind_problem(mode: int) -> str | None:
    """Why a file of this st_mode cannot be read as data, or None for a regular file."""
    if stat.S_ISREG(mode):
        return None
    kind = next((what for test, what in _KINDS if test(mode)), "a special file")
    return f"not a regular file: {kind}"


def checked_size(path: Path, limit: int, what: str = "such a file") -> int:
    """The size of the regular file at `path`, refusing special files and files over `limit` bytes."""
    try:
        st = os.stat(path)
    except OSError as e:
        raise BRDFLabError(f"cannot read: {e.strerror}", path) from None
    return _checked(path, st, limit, what)


def _checked(path: Path, st: os.stat_result, limit: int, what: str) -> int:
    problem = kind_problem(st.st_mode)
    if problem:
        raise BRDFLabError(problem, path)
    if st.st_size > limit:
        raise BRDFLabError(f"oversized: {st.st_size} bytes, {what} has at most {limit}", path)
    return st.st_size


class BoundedFile:
    """A regular file opened for reading after its type and size were checked.

    `size` is known before reading; `read(n)` returns exactly n bytes or raises (the file
    changed under us). Use as a context manager.
    """

    def __init__(self, path: str | os.PathLike, limit: int, what: str = "such a file") -> None:
        self.path = Path(path)
        try:
            fd = os.open(self.path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
        except OSError as e:
            raise BRDFLabError(f"cannot read: {e.strerror}", self.path) from None
        try:
            self.size = _checked(self.path, os.fstat(fd), limit, what)
            os.set_blocking(fd, True)
        except BaseException:
            os.close(fd)
            raise
        self._file = os.fdopen(fd, "rb")

    def read(self, n: int) -> bytes:
        try:
            data = self._file.read(n)
        except OSError as e:
            raise BRDFLabError(f"cannot read: {e.strerror}", self.path) from None
        if len(data) != n:
            raise BRDFLabError(f"the file changed while it was read ({len(data)} of {n} bytes)", self.path)
        return data

    def tell(self) -> int:
        return self._file.tell()

    @property
    def stream(self):
        """The underlying binary file, for parsers that read a header themselves."""
        return self._file

    def read_rest(self) -> bytes:
        return self.read(self.size - self._file.tell())

    def __enter__(self) -> "BoundedFile":
        return self

    def __exit__(self, *exc) -> None:
        self._file.close()


def read_bounded(path: str | os.PathLike, limit: int, what: str = "such a file") -> bytes:
    """All bytes of a regular file of at most `limit` bytes (`what` names the kind in errors)."""
    with BoundedFile(path, limit, what) as f:
        return f.read(f.size)


def file_sha256(path: str | os.PathLike, limit: int) -> str | None:
    """The sha256 of a regular file of at most `limit` bytes, read a MB at a time; None for a
    file that cannot be read, is special or is larger."""
    try:
        with BoundedFile(path, limit) as f:
            h = hashlib.sha256()
            for start in range(0, f.size, 1 << 20):
                h.update(f.read(min(1 << 20, f.size - start)))
    except BRDFLabError:
        return None
    return h.hexdigest()


def outside_problem(path: str | os.PathLike, folder: str | os.PathLike, sha256: str | None, limit: int,
                    what: str) -> str | None:
    """Why the folder policy (docs/hostile-input.md) refuses a file that a material names, or
    None: a file in the material's `folder` or below (links and `..` resolved) is opened, one
    elsewhere only when it matches the sha256 the material records (the lab records one
    whenever it saves such a reference). The reason says which rule failed and how."""
    if within(path, folder):
        return None
    if sha256 and file_sha256(path, limit) == sha256.strip().lower():
        return None
    lexical = Path(os.path.abspath(path)).is_relative_to(Path(os.path.abspath(folder)))
    where = "leads outside the material's folder through a link" if lexical else "lies outside the material's folder"
    why = "does not match the sha256 the material records" if sha256 else "the material records no sha256 for it"
    return f"the {what} {where} and {why}: refused by the folder policy (copy it next to the material)"


def within(path: str | os.PathLike, folder: str | os.PathLike) -> bool:
    """Whether `path` lies in `folder` or below once links and `..` are resolved."""
    try:
        return Path(path).resolve().is_relative_to(Path(folder).resolve())
    except (OSError, RuntimeError):  # a name too long, a link loop
        return False
