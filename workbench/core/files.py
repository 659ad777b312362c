"""Writing files atomically: to a temporary name beside the target, then renamed.

A crash or kill never leaves half a file under the real name (tables, renders, meshes,
DNG photos, truth files all go through here).
"""

from __future__ import annotations

import csv
import hashlib
import io
import os
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path


def atomic_write(path: str | Path, write: Callable[[Path], None]) -> Path:
    """Call ``write(tmp)`` on a temporary path with the same suffix, then rename it to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp{path.suffix}")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def atomic_write_npz(path: str | Path, **arrays) -> Path:
    """numpy.savez of ``arrays`` to ``path``, synced to disk before the rename (a checkpoint survives a crash)."""
    import numpy as np  # deferred: the kernel's other writers need no numpy

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
    return atomic_write(path, write)


def atomic_write_text(path: str | Path, text: str, *, sync: bool = False) -> Path:
    """Write ``text`` atomically; ``sync`` flushes it to disk before the rename."""
    def write(tmp: Path) -> None:
        with open(tmp, "w") as f:
            f.write(text)
            if sync:
                f.flush()
                os.fsync(f.fileno())
    return atomic_write(path, write)


def atomic_write_csv(path: str | Path, rows: list[dict]) -> Path:
    """Rows of dicts as CSV (columns: every key, sorted), written atomically."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=sorted({k for r in rows for k in r}), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return atomic_write_text(path, buffer.getvalue())


def file_sha256(path: str | Path) -> str:
    """The SHA-256 of a file's bytes, read in 1 MiB blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


SAFE_NAME_LENGTH = 64  # a name's share of a path: well under every file system's 255-byte limit
_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+")


def path_safe_name(name: str, max_length: int = SAFE_NAME_LENGTH) -> str:
    """A user's name (a structure's, a scene's) as one path component: characters other than
    letters, digits and ``. _ + -`` become ``_`` (``/``, ``..``, NUL, spaces, any non-ASCII), no
    leading dot (hidden files, ``..``), at most ``max_length`` characters; a name that had to
    change keeps a short hash of the original so that two names stay apart. Never empty.
    """
    safe = _UNSAFE.sub("_", name).lstrip(".") or "_"
    if safe == name and len(name) <= max_length:
        return name
    digest = hashlib.sha256(name.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    return f"{safe[:max_length - 9]}-{digest}"


def checked_lock_file(lock_file: Path) -> Path:
    """``lock_file``, refused by name when a folder or a symbolic link stands in its place
    (the flock would fail with EISDIR or ELOOP, which say nothing of what to do).

    Raises
    ------
    UserInputError
        When the path is a symbolic link or exists and is not a regular file.
    """
    from workbench.core.errors import UserInputError  # deferred: as in exclusive_output

    if lock_file.is_symlink() or (lock_file.exists() and not lock_file.is_file()):
        kind = "a symbolic link" if lock_file.is_symlink() else "a folder or other non-file"
        raise UserInputError(f"is {kind} where a lock file belongs", file=lock_file,
                             expected="a regular file or nothing: remove it (no running command holds it)")
    return lock_file


@contextmanager
def exclusive_output(path: str | Path, command: str, busy: str | None = None) -> Iterator[None]:
    """One ``command`` at a time writing ``path``: an ``flock`` (filelock) on ``.NAME.COMMAND.lock``
    beside it, taken without waiting; a second run into the same output is refused (UserInputError)
    while the first holds it (``busy``: the refusal's words). The lock dies with its process, so a
    killed run never leaves one behind."""
    from filelock import FileLock, Timeout  # deferred: only commands that write outputs take one

    from workbench.core.errors import UserInputError

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lock_file = checked_lock_file(path.parent / f".{path.name}.{command}.lock")
    lock = FileLock(str(lock_file))
    try:
        lock.acquire(timeout=0)
    except Timeout:
        raise UserInputError(busy or f"another {command} is writing this output now", file=path,
                             expected="to wait until it has finished, or another --out") from None
    try:
        yield
    finally:
        lock_file.unlink(missing_ok=True)  # while held, as workbench.core.cache.entry_lock: no lock file lingers
        lock.release()
