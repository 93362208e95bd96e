"""Safe outputs, shared by every writer: the one-line InputError, the check that an output never
replaces an input, and atomic replacement (temporary file in the destination folder, fsync, rename),
so that a crash or an error mid-way never leaves a partial or corrupt output behind.

Temporary files are named ``.NAME.p<pid>-<host>-<random>.partial.EXT`` and held under an exclusive
``flock`` while they are written. A process killed with SIGKILL cannot remove its temporary file;
the next write of the same output removes the stale ones: those of this output name whose writer
ran on this host, is no longer alive, and whose lock is free (the kernel drops a dead process's
locks). A live writer's file (its process alive or its lock held), a file written on another host
and any other file are never touched.

A run writes several files (the cloud, its summary, config, DTM, picture): inside ``output_group()``
each of them stays a temporary file until the whole group has succeeded, and all are then renamed
into place one after the other (signals held meanwhile); a failure or an interrupt anywhere in the
group removes them all, so that no output of the set is replaced unless every one of them was
written. A group's finished temporaries wait without their lock (a catalog's per-file outputs
would hold a descriptor each): other runs' clean-up leaves them alone while this process lives on
this host.
"""
from __future__ import annotations

import contextlib
import logging
import os
import re
import socket
import stat
import tempfile
import threading
from pathlib import Path
from typing import Iterable, Iterator

try:
    import fcntl
except ImportError:      # not POSIX: no locks, so no stale-file clean-up either
    fcntl = None

log = logging.getLogger("roadx_ti")


class InputError(ValueError):
    """A problem with a file the user named: one line, naming the file and the problem."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))  # always one line


def fail(path, problem: str) -> InputError:
    """The InputError for ``path``: 'PATH: problem'."""
    return InputError(f"{path}: {problem}")


def refuse_folder(output) -> None:
    """An output path that is an existing folder: one line naming a file to give instead."""
    out = Path(output)
    if out.is_dir():
        example = out / "result.laz" if not out.suffix else out.with_name(f"{out.stem}_2{out.suffix}")
        raise fail(out, f"is a folder, expected an output file name (e.g. {example})")


# bytes the temporary file (.STEM.p<pid>-<host>-<random>.partial.EXT) and the sidecars
# (STEM.summary.json, STEM.config.yaml, STEM.dtm.tif ...) add to an output's stem, with a margin
NAME_ADDITIONS = 80


def same_file(a, b) -> bool:
    """Whether paths ``a`` and ``b`` name one file: the same resolved path, or (both existing) the
    same file through a link."""
    a, b = Path(a), Path(b)
    if a.resolve() == b.resolve():
        return True
    if a.exists() and b.exists():
        with contextlib.suppress(OSError):
            return os.path.samefile(a, b)
    return False


def check_output_path(output, inputs: Iterable = ()) -> Path:
    """Refuse an output that is one of the inputs (same resolved path or same file through a
    link), or whose folder is missing or not writable. Returns the output as a Path."""
    out = Path(output)
    refuse_folder(out)
    resolved = out.resolve()
    for given in inputs:
        if given is not None and str(given) != "" and same_file(out, given):
            raise fail(out, f"refusing to write over the input file {given}; choose another output path")
    folder = resolved.parent
    if not folder.is_dir():
        raise fail(out, f"output folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise fail(out, f"output folder {folder} is not writable")
    try:
        name_max = os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):
        name_max = 255
    stem = len(os.fsencode(out.stem))
    if stem + NAME_ADDITIONS > name_max:
        raise fail(out, f"the file name is too long ({stem} bytes before its extension; the temporary and "
                        f"sidecar files add up to {NAME_ADDITIONS}, and this file system allows {name_max}); "
                        f"use at most {name_max - NAME_ADDITIONS} bytes")
    return out


def _fsync_path(path: Path, directory: bool = False) -> None:
    flags = os.O_RDONLY | (getattr(os, "O_DIRECTORY", 0) if directory else 0)
    try:
        fd = os.open(path, flags)
    except OSError:
        if directory:  # some platforms cannot open folders; the rename is still atomic
            return
        raise
    try:
        os.fsync(fd)
    except OSError:
        if not directory:
            raise
    finally:
        os.close(fd)


def _umask() -> int:
    """The process umask, read without changing it where the system allows (os.umask both sets and
    reads, which would race with other threads creating files)."""
    with contextlib.suppress(OSError, ValueError):
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def host_tag() -> str:
    """This host's name as temporary names carry it (letters, digits, _)."""
    return re.sub(r"[^A-Za-z0-9]", "_", socket.gethostname())[:32] or "host"


def _temporary_pattern(dest: Path) -> re.Pattern:
    return re.compile(re.escape(f".{dest.stem}.") + r"p(\d+)-([A-Za-z0-9_]+)-[A-Za-z0-9_]+"
                      + re.escape(f".partial{dest.suffix}") + "$")


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` runs (on this host); a process of another user counts as alive."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True          # someone else's process (or a number no process can have)
    return True


def _lock(fd: int) -> bool:
    """Take the exclusive lock of an open file without waiting; False when another holds it."""
    if fcntl is None:
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    return True


def remove_stale_temporaries(path) -> list[Path]:
    """Remove the temporary files of output ``path`` left by dead writers (module docstring);
    returns the removed paths."""
    dest = Path(path)
    if fcntl is None or not dest.parent.is_dir():
        return []
    pattern, host, removed = _temporary_pattern(dest), host_tag(), []
    try:
        names = os.listdir(dest.parent)
    except OSError:
        return []
    for name in names:
        m = pattern.match(name)
        if not m or m.group(2) != host or process_alive(int(m.group(1))):
            continue
        candidate = dest.parent / name
        try:
            if not stat.S_ISREG(os.lstat(candidate).st_mode):
                continue                      # never a link, a folder or a device
            fd = os.open(candidate, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        except OSError:
            continue
        try:
            if _lock(fd):
                os.unlink(candidate)
                removed.append(candidate)
        except OSError:
            pass
        finally:
            os.close(fd)
    for p in removed:
        log.info("removed %s, left by a run that was killed while writing %s", p.name, dest.name)
    return removed


class _Group:
    """Temporary files written inside output_group(), renamed into place when it succeeds."""

    def __init__(self):
        # (tmp, dest); their locks are let go (a catalog's per-file outputs would hold a descriptor
        # each); this process is alive, which keeps other runs' clean-up off them
        self.pending: list[tuple[Path, Path]] = []

    def commit(self) -> None:
        # what can be foreseen is checked before the first rename (a folder where a file goes)
        for _, dest in self.pending:
            if dest.is_dir():
                raise fail(dest, "is a folder; no output of the run was changed")
        folders = []
        try:
            while self.pending:
                tmp, dest = self.pending[0]
                os.replace(tmp, dest)
                RENAMED.append(dest)
                self.pending.pop(0)
                if dest.parent not in folders:
                    folders.append(dest.parent)
        except OSError as exc:
            raise fail(self.pending[0][1], f"renaming the written file into place failed "
                                           f"({exc.strerror or exc})") from exc
        for folder in folders:
            _fsync_path(folder, directory=True)

    def discard(self) -> None:
        for tmp, _ in self.pending:
            with contextlib.suppress(OSError):
                tmp.unlink()
        self.pending.clear()


_local = threading.local()      # per thread: its stack of open groups


def _stack() -> list:
    if not hasattr(_local, "groups"):
        _local.groups = []
    return _local.groups


@contextlib.contextmanager
def output_group() -> Iterator[None]:
    """Every atomic_output this thread completes inside the block is renamed into place only when
    the block succeeds, in the order they were written; on any exception or interrupt all of them are
    removed and every destination is left as it was (module docstring). Groups nest: an inner group
    commits into the outer one. Other threads' outputs are theirs (a thread's own group, or renamed
    at once)."""
    group, stack = _Group(), _stack()
    stack.append(group)
    try:
        yield
    except BaseException:
        stack.remove(group)
        group.discard()
        raise
    stack.remove(group)
    if stack:
        stack[-1].pending.extend(group.pending)
        group.pending.clear()
        return
    try:
        with _signals_held():
            group.commit()
    except BaseException:
        group.discard()
        raise


@contextlib.contextmanager
def _signals_held():
    """Ctrl-C, SIGTERM and SIGHUP wait until the block is done (the renames of a group: an interrupt
    between two of them would leave a mixed set); raised after it. Main thread only."""
    import signal

    held = {getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)}
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


# the outputs renamed into place, complete, in this process (an interrupt arriving after a group's
# renames, which hold signals, is reported with them: the run's files are the new ones)
RENAMED: list = []


def _open_group():
    stack = _stack()
    return stack[-1] if stack else None


@contextlib.contextmanager
def atomic_output(path) -> Iterator[Path]:
    """``with atomic_output(p) as tmp: write tmp`` -> ``tmp`` is fsynced and renamed to ``p`` when
    the block succeeds; on any exception it is removed and ``p`` is left as it was. The temporary
    name is hidden, in the destination's folder (same file system, so the rename is atomic), and
    ends with the destination's suffix so writers that choose a format by extension still work.
    Stale temporary files of the same output left by killed runs are removed first."""
    dest = Path(path)
    remove_stale_temporaries(dest)
    try:
        fd, name = tempfile.mkstemp(dir=dest.parent, prefix=f".{dest.stem}.p{os.getpid()}-{host_tag()}-",
                                    suffix=f".partial{dest.suffix}")
    except OSError as exc:  # e.g. /proc, a read-only mount: the user's path, not a program error
        raise fail(dest, f"cannot create a file in the output folder {dest.parent} "
                         f"({exc.strerror or type(exc).__name__})") from None
    _lock(fd)                # held until the file is renamed or removed: it is live
    tmp = Path(name)
    group = None
    try:
        yield tmp
        _fsync_path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual permissions
        group = _open_group()
        if group is None:
            os.replace(tmp, dest)
            RENAMED.append(dest)
        else:
            group.pending.append((tmp, dest))    # renamed when the group commits
    except BaseException as exc:
        group = None
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) or _is_write_error(exc):
            # disk full, I/O error: one line, the output left as it was
            raise fail(dest, f"writing failed ({_write_error_text(exc)}); the output was not changed") from exc
        raise
    finally:
        os.close(fd)
    if group is None:
        _fsync_path(dest.parent, directory=True)


class WriteFailure(RuntimeError):
    """A writer's own report of a failed write (a full disk, an I/O error): said like an OSError."""


def _is_write_error(exc: BaseException) -> bool:
    """An I/O failure that a compression library reports as its own type (lazrs: 'IoError: Failed
    to call write'), or a WriteFailure (copclib's, io.copc)."""
    return isinstance(exc, WriteFailure) or (type(exc).__name__ == "LazrsError" and "IoError" in str(exc))


def _write_error_text(exc: BaseException) -> str:
    if isinstance(exc, OSError):
        return str(exc.strerror or exc)
    return " ".join(str(exc).split()) + ": disk full or an I/O error"
