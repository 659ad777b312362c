"""The user's cache: rebuildable entries (efficiency tables, meshes) shared by every folder.

Where it is, first match wins: ``--cache DIR`` on the command line (which sets
``WORKBENCH_CACHE`` for the process and the dask workers it starts), the environment
variable ``WORKBENCH_CACHE``, ``$XDG_CACHE_HOME/workbench``, ``~/.cache/workbench``.
Entries live in one folder per kind (``tables/``, ``meshes/``) under names made from the
content hash of what they hold, so a command run from any folder finds them.

Several processes may want one entry at once (two renders of one scene, dask workers on
one machine, a verify run beside a render). ``entry_lock`` guards an entry with a file
lock (an ``flock`` through the filelock package) on ``.<name>.lock`` beside it: the
first process builds, the others wait (saying so on stderr) and then find the finished
entry. The holder removes the lock file before it lets go, so no lock files linger; a
waiter that locked the removed file sees it is gone and locks the new one (filelock
checks the file's link count after each lock). ``clear`` removes an entry while holding
its lock, and keeps entries whose lock a running build holds.

This module is part of the shared kernel: it imports no other project package.
"""

from __future__ import annotations

import os
import secrets
import shutil
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from filelock import FileLock, Timeout

from workbench.core.files import checked_lock_file, path_safe_name

ENVIRONMENT_VARIABLE = "WORKBENCH_CACHE"
KINDS = ("tables", "meshes")


def cache_root() -> Path:
    """The cache folder for this process (see the module docstring for the order)."""
    chosen = os.environ.get(ENVIRONMENT_VARIABLE)
    if chosen:
        return Path(chosen).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg and os.path.isabs(xdg) else Path.home() / ".cache"  # the XDG spec ignores relative paths
    return base / "workbench"


def use_cache_root(folder: str | os.PathLike[str]) -> Path:
    """Make ``folder`` the cache of this process and of the processes it starts (``--cache``).

    Raises ``NotADirectoryError`` when ``folder`` is an existing file (the command line
    turns it into a user error).
    """
    path = Path(folder).expanduser().absolute()
    if path.exists() and not path.is_dir():
        raise NotADirectoryError(str(path))
    os.environ[ENVIRONMENT_VARIABLE] = str(path)
    return path


def entry_path(kind: str, name: str) -> Path:
    """Where the entry ``name`` of ``kind`` (one of KINDS) lives in the cache."""
    if kind not in KINDS:
        raise ValueError(f"unknown cache kind {kind!r}; expected one of {KINDS}")
    if name != path_safe_name(name, max_length=len(name)):  # a name is never a path (workbench.core.files.path_safe_name)
        raise ValueError(f"a cache entry's name must be one safe path component, got {name!r}")
    return cache_root() / kind / name


def lock_path(entry: Path) -> Path:
    """The lock file that guards ``entry``: hidden, beside it."""
    return entry.parent / f".{entry.name}.lock"


def _say(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


@contextmanager
def entry_lock(entry: str | os.PathLike[str], *, notify: Callable[[str], None] | None = None) -> Iterator[None]:
    """Hold ``entry``'s lock for the block. When another process holds it, ``notify`` (by
    default a line on stderr) says so once and the call waits until it is released.
    """
    lock_file = lock_path(Path(entry))
    lock_file.parent.mkdir(parents=True, exist_ok=True)
    lock = FileLock(str(checked_lock_file(lock_file)))
    try:
        lock.acquire(timeout=0)
    except Timeout:
        (notify or _say)(f"waiting for another process that is building {entry} (lock {lock_file}) ...")
        lock.acquire()
    try:
        yield
    finally:
        lock_file.unlink(missing_ok=True)  # while held: waiters on it retry on a new file (see the module docstring)
        lock.release()


def is_locked(entry: Path) -> bool:
    """Whether a running process holds ``entry``'s lock now."""
    lock_file = lock_path(entry)
    if not lock_file.exists():
        return False
    lock = FileLock(str(lock_file))
    try:
        lock.acquire(timeout=0)
    except Timeout:
        return True
    lock.release()
    return False


@dataclass(frozen=True)
class CacheEntry:
    kind: str
    path: Path
    bytes: int
    modified: float  # newest modification time of its files (seconds since the epoch)
    locked: bool

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def age_s(self) -> float:
        return max(0.0, time.time() - self.modified)


def _files(path: Path) -> list[Path]:
    return [path] if path.is_file() else [f for f in path.rglob("*") if f.is_file()]


def _describe(kind: str, path: Path) -> CacheEntry:
    sizes, newest = 0, path.stat().st_mtime
    for f in _files(path):
        try:
            stat = f.stat()
        except FileNotFoundError:  # removed while we looked (a build replacing a file)
            continue
        sizes += stat.st_size
        newest = max(newest, stat.st_mtime)
    return CacheEntry(kind, path, sizes, newest, is_locked(path))


def entries(root: Path | None = None) -> list[CacheEntry]:
    """Every entry in the cache (lock files and temporary files left out), by kind and name."""
    root = cache_root() if root is None else root
    found = []
    for folder in sorted(p for p in root.iterdir() if p.is_dir()) if root.is_dir() else []:
        for path in sorted(folder.iterdir()):
            if not path.name.startswith("."):
                found.append(_describe(folder.name, path))
    return found


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


READER_PREFIX = ".reader-"


@contextmanager
def reading(root: Path | None = None) -> Iterator[None]:
    """Mark the cache as read by this process for the block (a render: its meshes and tables are read
    by Mitsuba after they were built). Each reader holds an ``flock`` on its own file
    ``.reader-PID-TOKEN.lock`` at the cache's root, so readers never wait for each other; ``clear``
    removes nothing while any reader holds its lock (issue 46, cause 5: a clear during a render
    deleted the meshes the render had just built). A killed reader's lock dies with it."""
    root = cache_root() if root is None else root
    marker = root / f"{READER_PREFIX}{os.getpid()}-{secrets.token_hex(4)}.lock"
    lock = FileLock(str(marker))
    try:
        root.mkdir(parents=True, exist_ok=True)
        lock.acquire()
    except OSError:  # a read-only cache: nobody can clear it either, so there is nothing to guard
        yield
        return
    while not marker.exists():  # a clear took it for a dead reader's between its creation and the lock
        lock.release()
        lock.acquire()
    try:
        yield
    finally:
        lock.release()
        marker.unlink(missing_ok=True)


def readers(root: Path | None = None) -> int:
    """How many processes read the cache now (``reading``); stale markers of dead readers are removed."""
    root = cache_root() if root is None else root
    active = 0
    for marker in root.glob(f"{READER_PREFIX}*.lock") if root.is_dir() else []:
        lock = FileLock(str(marker))
        try:
            lock.acquire(timeout=0)
        except Timeout:
            active += 1
            continue
        try:
            marker.unlink(missing_ok=True)  # nobody held it: a reader that died without removing it
        finally:
            lock.release()
    return active


def clear(root: Path | None = None) -> tuple[list[CacheEntry], list[CacheEntry]]:
    """Remove every entry no running build holds, none while a render reads the cache (``reading``):
    (removed, kept because locked or read)."""
    root = cache_root() if root is None else root
    if readers(root):
        return [], entries(root)
    removed, kept = [], []
    for entry in entries(root):
        if _remove_unless_locked(entry.path, lock_path(entry.path)):
            removed.append(entry)
        else:
            kept.append(entry)
    for orphan in root.glob("*/.*.lock"):  # locks of entries that were never finished
        unfinished = orphan.with_name(orphan.name[1:-len(".lock")])
        if not unfinished.exists():
            _remove_unless_locked(unfinished, orphan)
    return removed, kept


def _remove_unless_locked(entry: Path, lock_file: Path) -> bool:

    lock = FileLock(str(lock_file))
    try:
        lock.acquire(timeout=0)
    except Timeout:
        return False
    try:
        _remove(entry)
        lock_file.unlink(missing_ok=True)  # a waiter that opened it retries on the new file (filelock checks)
    finally:
        lock.release()
    return True
