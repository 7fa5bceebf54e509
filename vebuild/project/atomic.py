"""Atomic file writes: the one way vebuild puts a file (or a folder) in place.

Every file vebuild writes is first written to a unique temporary name beside its target,

    ``.NAME.<pid>.<8 hex digits>.vebuild-tmp``

flushed and fsync'ed, given the old file's permission bits (if there was one), renamed over the
target with :func:`os.replace` (one rename within one file system: a reader, or a crash, sees the
old file or the new one, never a half-written one), and the folder is fsync'ed so that the rename
itself is durable. On any failure the temporary file is removed and the old file is left as it was.

A process killed with SIGKILL cannot remove its temporary file; :func:`clean_stale` removes such
leftovers (only names of the pattern above, whose process is gone) and is called at the start of
every stage that writes. Folders are replaced the same way (:func:`replace_folder`): built under a
temporary sibling name, the old one renamed aside (``.NAME.<pid>.<hex>.vebuild-old``), the new one
renamed into place, then the old one deleted; a new folder is put where there was none (or an
empty one) by :func:`place_folder`, which never replaces anything.

Layer: file I/O (no GL, no project logic). Errors are raised as :class:`OSError`; callers turn them
into messages that name what they were writing.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import secrets
import shutil
import stat
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import BinaryIO

#: What a vebuild temporary file or folder is called (``.NAME.<pid>.<hex>.vebuild-tmp``; an old
#: folder set aside while a new one is moved in: ``….vebuild-old``).
TEMP_PATTERN = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)\.[0-9a-f]{8}\.vebuild-(?P<kind>tmp|old)$")

#: A folder vebuild may remove as a stale temporary one holds this file (its output manifest).
MANIFEST = ".vebuild-output.json"


def temp_path(target: str | os.PathLike[str], kind: str = "tmp") -> Path:
    """A fresh temporary name beside ``target`` (not created)."""
    target = Path(target)
    return target.with_name(f".{target.name}.{os.getpid()}.{secrets.token_hex(4)}.vebuild-{kind}")


def is_temp_name(name: str) -> bool:
    return TEMP_PATTERN.match(name) is not None


def fsync_folder(folder: str | os.PathLike[str]) -> None:
    """Make renames in ``folder`` durable (POSIX; a no-op where folders cannot be opened)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _old_mode(target: Path) -> int | None:
    try:
        st = os.stat(target)
    except OSError:
        return None
    return st.st_mode & 0o7777


@contextlib.contextmanager
def staged(target: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path beside ``target`` to write into (by any means, e.g. a library that wants a
    file name); when the block ends without an error it is fsync'ed and renamed over ``target``.
    On an error, or if nothing was written, the temporary file is removed and ``target`` is
    untouched."""
    with _staged(Path(target), synced=False) as tmp:
        yield tmp


@contextlib.contextmanager
def _staged(target: Path, synced: bool) -> Iterator[Path]:
    tmp = temp_path(target)
    try:
        yield tmp
        commit(tmp, target, synced)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def commit(tmp: Path, target: Path, synced: bool = False) -> None:
    """fsync ``tmp`` (unless the writer did: ``synced``), give it the old target's mode, rename
    it over ``target``, fsync the folder."""
    if not synced:
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    mode = _old_mode(target)
    if mode is not None:
        os.chmod(tmp, mode)
    os.replace(tmp, target)
    fsync_folder(target.parent)


def write_with(target: str | os.PathLike[str], writer: Callable[[BinaryIO], None]) -> Path:
    """Atomically write ``target`` with ``writer(fileobj)`` (binary, opened for writing)."""
    target = Path(target)
    with _staged(target, synced=True) as tmp:
        # os.open honours the umask (mkstemp would make the file private).
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        with open(fd, "wb") as f:
            writer(f)
            f.flush()
            os.fsync(f.fileno())
    return target


def write_via_path(target: str | os.PathLike[str], writer: Callable[[Path], None]) -> Path:
    """Atomically write ``target`` with ``writer(temp_path)``, for libraries that write to a
    file name themselves (Pillow with a format, PyAV)."""
    target = Path(target)
    with staged(target) as tmp:
        writer(tmp)
        if not tmp.is_file():
            raise FileNotFoundError(2, "the writer wrote no file", str(tmp))
    return target


def write_bytes(target: str | os.PathLike[str], data: bytes) -> Path:
    """Atomically write ``data`` to ``target``."""

    def write(f: BinaryIO) -> None:
        f.write(data)

    return write_with(target, write)


def write_text(target: str | os.PathLike[str], text: str, encoding: str = "utf-8") -> Path:
    """Atomically write ``text`` to ``target`` (``\\n`` line ends, as given)."""
    return write_bytes(target, text.encode(encoding))


class LinkOnTheWay(OSError):
    """A folder on the way to a target, below the folder given as ``within``, is a symbolic link."""


def _open_folder(folder: Path, within: Path | None) -> int:
    """A descriptor of ``folder``. Below ``within`` (when given) it is opened one name at a time,
    none followed if it is a symbolic link: a link put in place of a folder at any moment gives
    an error, never a write through it."""
    flags = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0)
    if within is None:
        return os.open(folder, flags)
    fd = os.open(within, flags)
    where = within
    try:
        for name in folder.relative_to(within).parts:
            where = where / name
            try:
                nxt = os.open(name, flags | os.O_NOFOLLOW, dir_fd=fd)
            except OSError as e:
                if os.path.islink(where):
                    raise LinkOnTheWay(errno.ELOOP, "is a symbolic link; vebuild does not write through links",
                                       str(where)) from e
                raise
            os.close(fd)
            fd = nxt
    except BaseException:
        os.close(fd)
        raise
    return fd


def write_many(files: Sequence[tuple[Path, bytes]], within: Path | None = None) -> None:
    """Write every file to its temporary name first, then rename them in order (the last one,
    by convention the file that names the others, goes in last). On an error before the renames
    nothing is changed; no temporary file is left in any case. ``within``: a folder that holds
    every target; no folder below it is gone through if it is a symbolic link (each is opened
    without following links, and every write and rename is made relative to it)."""
    temps: list[tuple[int, str, Path]] = []
    replaced: list[Path] = []
    folders: dict[Path, int] = {}
    final = files[0][0] if files else Path()
    try:
        for final, data in files:
            if final.parent not in folders:
                folders[final.parent] = _open_folder(final.parent, within)
            dfd = folders[final.parent]
            tmp = temp_path(final).name
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o666, dir_fd=dfd)
            temps.append((dfd, tmp, final))
            with open(fd, "wb") as f:
                f.write(data)
                f.flush()
                mode = _old_mode_at(dfd, final.name)
                if mode is not None:
                    os.fchmod(f.fileno(), mode)
                os.fsync(f.fileno())
        for dfd, tmp, final in temps:
            os.replace(tmp, final.name, src_dir_fd=dfd, dst_dir_fd=dfd)
            replaced.append(final)
        for dfd in folders.values():
            with contextlib.suppress(OSError):
                os.fsync(dfd)
    except OSError as e:
        # Name the target, not its temporary; say which targets were already replaced.
        err = OSError(e.errno, e.strerror or str(e), e.filename if isinstance(e, LinkOnTheWay) else str(final))
        err.replaced = replaced  # type: ignore[attr-defined]
        raise err from e
    finally:
        for dfd, tmp, _ in temps:
            with contextlib.suppress(OSError):
                os.unlink(tmp, dir_fd=dfd)
        for dfd in folders.values():
            os.close(dfd)


def _old_mode_at(dfd: int, name: str) -> int | None:
    try:
        st = os.stat(name, dir_fd=dfd, follow_symlinks=False)
    except OSError:
        return None
    return st.st_mode & 0o7777 if stat.S_ISREG(st.st_mode) else None


def remove_tree(folder: Path) -> None:
    """Delete a folder vebuild made (a temporary or set-aside one, or its own output folder)."""
    shutil.rmtree(folder, ignore_errors=True)


def replace_folder(new: Path, target: Path) -> None:
    """Move the finished folder ``new`` to ``target``: the old ``target`` (if any) is renamed aside,
    ``new`` renamed into place, then the old one deleted. The caller has checked that an old
    ``target`` may be deleted. After a crash between the two renames, :func:`clean_stale` puts
    the set-aside folder back."""
    aside = None
    if target.exists() or target.is_symlink():
        aside = temp_path(target, "old")
        os.replace(target, aside)
    try:
        os.replace(new, target)
    except BaseException:
        if aside is not None:
            os.replace(aside, target)
        raise
    fsync_folder(target.parent)
    if aside is not None:
        remove_tree(aside)


def place_folder(new: Path, target: Path) -> None:
    """Move the finished folder ``new`` to ``target``, a name that is free or an empty folder: one
    rename, which the system refuses (:class:`OSError`) where ``target`` has meanwhile become a
    file, a link to a folder or a folder with anything in it, so that nothing is ever replaced
    (:func:`replace_folder` replaces). ``new`` is left where it was then."""
    os.rename(new, target)
    fsync_folder(target.parent)


def _process_gone(pid: int) -> bool:
    if pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:  # exists, owned by someone else
        return False
    return False


def _only_temporaries(folder: Path) -> bool:
    """A folder that holds nothing, or only vebuild's temporary files (one killed as it began)."""
    try:
        return all(e.is_file(follow_symlinks=False) and is_temp_name(e.name) for e in os.scandir(folder))
    except OSError:
        return False


def clean_stale(folder: str | os.PathLike[str]) -> list[Path]:
    """Remove vebuild's own temporaries left in ``folder`` by a process that died (a name of
    :data:`TEMP_PATTERN` whose process is gone; a folder only if it holds vebuild's manifest) and
    put back a folder set aside by a replacement that did not finish. Nothing else is touched.
    Returns what was removed."""
    folder = Path(folder)
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for e in entries:
        m = TEMP_PATTERN.match(e.name)
        if m is None or not _process_gone(int(m["pid"])):
            continue
        path = folder / e.name
        try:
            if e.is_symlink():
                continue
            if e.is_dir():
                if not (path / MANIFEST).is_file() and not _only_temporaries(path):
                    continue  # not recognisably vebuild's: leave it
                home = folder / m["name"]
                if m["kind"] == "old" and not home.exists() and not home.is_symlink():
                    os.replace(path, home)  # the replacement stopped between its two renames
                    continue
                remove_tree(path)
            elif e.is_file():
                os.unlink(path)
            else:
                continue
            removed.append(path)
        except OSError:
            continue
    if removed:
        fsync_folder(folder)
    return removed
