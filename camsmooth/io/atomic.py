"""Atomic file output: write to a temporary beside the final name, then rename, so a failed or
interrupted run never leaves a partial output behind and never removes what it did not write.

- ``atomic_path`` / ``write_text_atomic`` / ``write_atomic``: one file.
- ``atomic_dir``: a folder of files (a report). By default the folder's own files are moved
  *into* an existing folder one by one (each replaced atomically; other files there are left
  alone); ``replace=True`` swaps the whole folder, and refuses the current folder, an ancestor
  of it, the home folder or the root.
- ``output_transaction``: every output of one command as one transaction. Each output is written
  to a temporary beside its final name; when the block ends without an exception all of them are
  moved into place (old versions restored if a move fails); on an exception, SIGINT or SIGTERM
  the temporaries are removed, so neither a partial output nor an earlier output of the same
  command is left behind.

OS errors are re-raised naming the user's path, never a temporary one.
"""

from __future__ import annotations

import errno
import os
import shutil
import signal
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

_TMP_TAG = ".camsmooth-"


class Terminated(KeyboardInterrupt):
    """SIGTERM turned into an exception so that cleanup (``finally``, context managers) runs; a
    KeyboardInterrupt subclass because it is an interruption by the user or the system."""

    signum = signal.SIGTERM


def _default_mode(base: int) -> int:
    """The mode a plain open() would give (mkstemp/mkdtemp use 0600/0700)."""
    umask = os.umask(0)
    os.umask(umask)
    return base & ~umask


def _user_name(name: object, names: dict[str, str]) -> object:
    """``name`` with a temporary (or a path inside a temporary folder) replaced by the final name."""
    if not isinstance(name, (str, os.PathLike)):
        return name
    text = os.fspath(name)
    for tmp, final in names.items():
        if text == tmp:
            return final
        if text.startswith(tmp + os.sep):
            return final + text[len(tmp):]
    return name


def _renamed(exc: OSError, names: dict[str, str]) -> OSError:
    """``exc`` with temporary file names replaced by the user's names (same class and errno)."""
    f1, f2 = (_user_name(f, names) for f in (exc.filename, exc.filename2))
    if (f1, f2) == (exc.filename, exc.filename2) or exc.errno is None:
        return exc
    new = OSError(exc.errno, exc.strerror, f1, None, f2) if f2 is not None else OSError(exc.errno, exc.strerror, f1)
    new.__traceback__ = exc.__traceback__
    return new


def _ensure_folder(folder: Path, created: list[Path] | None = None) -> None:
    """Create ``folder`` and missing parents; a file in the way is a NotADirectoryError naming it.

    Folders created are appended to ``created`` (outermost first) so a rollback can remove them.
    """
    missing: list[Path] = []
    p = folder
    while not p.exists():
        if p.is_symlink():  # a dangling link: mkdir would fail with a confusing message
            raise FileNotFoundError(errno.ENOENT, "a link to a missing folder", str(p))
        missing.append(p)
        if p.parent == p:
            break
        p = p.parent
    if p.exists() and not p.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, "is a file, not a folder", str(p))
    for q in reversed(missing):
        try:
            q.mkdir()
        except FileExistsError:
            if not q.is_dir():
                raise NotADirectoryError(errno.ENOTDIR, "is a file, not a folder", str(q)) from None
            continue
        if created is not None:
            created.append(q)


def _check_file_target(path: Path) -> None:
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a folder; a file name is needed here", str(path))


def _mkstemp_beside(path: Path, suffix: str | None = None) -> Path:
    """An empty temporary file in ``path``'s folder, or an OSError naming ``path`` (not the temporary)."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}{_TMP_TAG}", suffix=suffix or path.suffix,
                                   dir=path.parent)
    except OSError as exc:
        # ENOENT in an existing folder (/proc) would read "file not found": say what it means
        reason = "cannot create files in this folder" if exc.errno == errno.ENOENT else exc.strerror
        raise OSError(exc.errno, reason, str(path)) from None
    os.close(fd)
    return Path(tmp)


@contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it onto ``path``.

    Missing parent folders are created. On an exception the temporary file is removed and
    ``path`` is left untouched; an OSError names ``path``, not the temporary.
    """
    path = Path(path)
    _ensure_folder(path.parent)
    _check_file_target(path)
    tmp_path = _mkstemp_beside(path, suffix)
    try:
        yield tmp_path
        if tmp_path.exists():
            os.chmod(tmp_path, _default_mode(0o666))
        os.replace(tmp_path, path)
    except OSError as exc:
        raise _renamed(exc, {str(tmp_path): str(path)}) from None
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_atomic(path: str | os.PathLike, writer: Callable[[Path], None]) -> None:
    """Call ``writer(tmp_path)`` and move the result onto ``path`` atomically."""
    with atomic_path(path) as tmp:
        writer(tmp)


# ----------------------------------------------------------------------------------------------
# folders
def _home() -> Path | None:
    try:
        return Path(os.path.realpath(Path.home()))
    except (RuntimeError, KeyError):  # no HOME and no password entry
        return None


def _refuse_replace(path: Path, keep: Iterable[str | os.PathLike] = ()) -> None:
    """OSError unless replacing the folder ``path`` whole is safe: not the current folder or an
    ancestor of it, not the home folder or the root, and holding none of the paths in ``keep``."""
    real = Path(os.path.realpath(path))
    cwd = Path(os.path.realpath(os.getcwd()))
    why = None
    if real == cwd or real in cwd.parents:
        why = "it is the current folder or holds it"
    elif real == _home() or real.parent == real:
        why = "it is the home folder or the root"
    else:
        for k in keep:
            kr = Path(os.path.realpath(k))
            if kr == real or real in kr.parents:
                why = f"it holds {k}, an input or output of this command"
                break
    if why:
        raise OSError(errno.EPERM, f"will not replace this folder whole ({why})", str(path))


def _merge_plan(src: Path, dst: Path) -> list[tuple[Path, Path]]:
    """(source, destination) moves that put every entry of ``src`` into ``dst`` (existing folders
    are merged recursively); OSError if a file would replace a folder or the other way round."""
    moves: list[tuple[Path, Path]] = []
    for entry in sorted(src.iterdir()):
        target = dst / entry.name
        if entry.is_dir() and not entry.is_symlink():
            if target.is_dir() and not target.is_symlink():
                moves += _merge_plan(entry, target)
                continue
            if target.exists() or target.is_symlink():
                raise NotADirectoryError(errno.ENOTDIR, "a file is in the way of a folder to write", str(target))
        elif target.is_dir() and not target.is_symlink():
            raise IsADirectoryError(errno.EISDIR, "a folder is in the way of a file to write", str(target))
        moves.append((entry, target))
    return moves


def _stage_dir(path: Path, replace: bool, created: list[Path] | None = None) -> Path:
    """A temporary folder for the folder output ``path``: inside ``path`` when it exists and is
    merged into (its own parent may not be writable, e.g. the current folder), else beside it."""
    if path.exists() and not path.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, "is a file; a folder is needed here", str(path))
    inside = path.is_dir() and not replace
    parent = path if inside else path.parent
    _ensure_folder(parent, created)
    try:
        return Path(tempfile.mkdtemp(prefix=_TMP_TAG if inside else f".{path.name}{_TMP_TAG}", dir=parent))
    except OSError as exc:
        reason = "cannot create files in this folder" if exc.errno == errno.ENOENT else exc.strerror
        raise OSError(exc.errno, reason, str(path)) from None


@contextmanager
def atomic_dir(path: str | os.PathLike, *, replace: bool = False,
               keep: Iterable[str | os.PathLike] = ()) -> Iterator[Path]:
    """Yield a temporary folder; on success install its contents at ``path``.

    ``path`` missing: the folder is renamed into place. ``path`` an existing folder: each entry
    written is moved into it (replacing the same name atomically; other files stay), or with
    ``replace=True`` the whole folder is swapped (refused for the current folder, its ancestors,
    the home folder, the root, and a folder holding any path in ``keep``). On an exception
    nothing at ``path`` changes. OSError (naming ``path``) if it cannot be done.
    """
    with output_transaction() as tx:
        yield tx.folder(path, replace=replace, keep=keep)


# ----------------------------------------------------------------------------------------------
# transactions
@dataclass
class _Staged:
    tmp: Path
    final: Path
    folder: bool
    replace: bool = False
    keep: tuple[str, ...] = ()


@dataclass
class OutputTransaction:
    """The outputs of one command (``output_transaction``). ``file(p)`` / ``folder(p)`` return the
    temporary to write; nothing reaches a final name before ``commit``."""

    staged: list[_Staged] = field(default_factory=list)
    created: list[Path] = field(default_factory=list)
    committed: bool = False

    def _check_new(self, final: Path) -> None:
        real = os.path.realpath(final)
        for s in self.staged:
            if os.path.realpath(s.final) == real:
                raise OSError(errno.EEXIST, "named twice as an output of this command", str(final))

    def file(self, path: str | os.PathLike) -> Path:
        """A temporary file beside ``path`` (missing folders are created; removed again on rollback)."""
        final = Path(path)
        self._check_new(final)
        for s in self.staged:  # a folder to be replaced whole must not hold this output
            if s.replace and s.final.exists():
                _refuse_replace(s.final, (final,))
        try:
            _ensure_folder(final.parent, self.created)
        except OSError as exc:  # names a folder on the way: say which output needed it
            raise OSError(exc.errno, f"{exc.strerror} (on the way to {final})", exc.filename) from None
        _check_file_target(final)
        tmp = _mkstemp_beside(final)
        self.staged.append(_Staged(tmp, final, folder=False))
        return tmp

    def folder(self, path: str | os.PathLike, *, replace: bool = False,
               keep: Iterable[str | os.PathLike] = ()) -> Path:
        """A temporary folder for ``path`` (see ``atomic_dir`` for merge / replace)."""
        final = Path(path)
        self._check_new(final)
        keep = tuple(str(k) for k in keep)
        if replace and final.exists():
            _refuse_replace(final, keep + tuple(str(s.final) for s in self.staged))
        tmp = _stage_dir(final, replace, self.created)
        self.staged.append(_Staged(tmp, final, folder=True, replace=replace, keep=keep))
        return tmp

    def names(self) -> dict[str, str]:
        """Temporary name -> final name (for messages)."""
        return {str(s.tmp): str(s.final) for s in self.staged}

    # -- commit ----------------------------------------------------------------------------------
    def _plan(self) -> list[tuple[Path, Path, Path | None]]:
        """Every rename of the commit as (source, destination, folder to remove afterwards), all
        checked before anything moves."""
        plan: list[tuple[Path, Path, Path | None]] = []
        finals = [str(s.final) for s in self.staged]
        for s in self.staged:
            if not s.folder:
                _check_file_target(s.final)
                plan.append((s.tmp, s.final, None))
            elif s.final.is_dir() and not s.replace:
                plan += [(a, b, None) for a, b in _merge_plan(s.tmp, s.final)]
                plan.append((s.tmp, s.final, s.tmp))  # marks the temporary folder for removal
            else:
                if s.final.exists():
                    if not s.final.is_dir():
                        raise NotADirectoryError(errno.ENOTDIR, "is a file; a folder is needed here", str(s.final))
                    _refuse_replace(s.final, s.keep + tuple(f for f in finals if f != str(s.final)))
                plan.append((s.tmp, s.final, None))
        return plan

    def commit(self) -> None:
        """Move every staged output into place; on failure restore what was there and re-raise."""
        plan = self._plan()
        undo: list[Callable[[], None]] = []
        trash: list[Path] = []
        with _signals_deferred():  # a signal between two renames would leave half a commit
            try:
                for src, dst, remove in plan:
                    if remove is not None:
                        trash.append(remove)
                        continue
                    undo.append(_install(src, dst, trash))
                self.committed = True
            except BaseException:
                for u in reversed(undo):
                    try:
                        u()
                    except OSError:
                        pass
                raise
            finally:
                for t in trash:
                    _remove(t)

    def rollback(self) -> None:
        """Remove every temporary, and the folders created for the outputs when left empty."""
        for s in self.staged:
            _remove(s.tmp)
        for folder in reversed(self.created):
            try:
                folder.rmdir()
            except OSError:
                pass


@contextmanager
def _signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM until the block is over, then deliver them to the handlers that were
    installed. Python runs signal handlers in the main thread whichever thread the OS picked, so
    swapping the Python-level handlers defers them reliably (a thread signal mask would not)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    old = {}
    # the OS holds the signals arriving now (pthread_sigmask); the Python handlers are swapped
    # too, for a signal the C level caught just before the mask whose handler has yet to run
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)
    try:
        for sig in _SIGNALS:
            if signal.getsignal(sig) is not None:  # None: a handler not set from Python, left alone
                old[sig] = signal.signal(sig, lambda signum, frame: pending.append(signum))
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # held signals reach the restored handlers
        for sig in dict.fromkeys(pending):
            signal.raise_signal(sig)


def _remove(p: Path) -> None:
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p, ignore_errors=True)
    elif p.exists() or p.is_symlink():
        try:
            p.unlink()
        except OSError:
            pass


def _install(src: Path, dst: Path, trash: list[Path]) -> Callable[[], None]:
    """Rename ``src`` onto ``dst``; return the undo. A replaced file is kept as a hard link (a
    copy where links are not possible) until the commit is over; a replaced folder is renamed
    aside. Both go to ``trash``."""
    if dst.is_dir() and not dst.is_symlink():  # whole-folder replace (checked by _plan)
        aside = Path(tempfile.mkdtemp(prefix=f".{dst.name}{_TMP_TAG}old-", dir=dst.parent))
        aside.rmdir()
        os.rename(dst, aside)
        try:
            os.rename(src, dst)
        except OSError:
            os.rename(aside, dst)
            raise
        os.chmod(dst, _default_mode(0o777))
        trash.append(aside)

        def undo_dir() -> None:
            _remove(dst)
            os.rename(aside, dst)
            trash.remove(aside)
        return undo_dir
    if src.is_dir():
        os.chmod(src, _default_mode(0o777))
    elif src.exists():
        os.chmod(src, _default_mode(0o666))
    backup = None
    if dst.exists() or dst.is_symlink():
        backup = dst.with_name(f".{dst.name}{_TMP_TAG}old-{os.getpid()}-{id(src):x}")
        _remove(backup)  # only ever a leftover of this module (the tag)
        try:
            os.link(dst, backup, follow_symlinks=False)
        except OSError:
            shutil.copy2(dst, backup, follow_symlinks=False)
        trash.append(backup)
    os.replace(src, dst)

    def undo_file() -> None:
        if backup is not None:
            os.replace(backup, dst)
            trash.remove(backup)
        else:
            _remove(dst)
    return undo_file


@contextmanager
def output_transaction() -> Iterator[OutputTransaction]:
    """All outputs of one command as one transaction (module docstring).

    ``with output_transaction() as tx:`` write each output to ``tx.file(final)`` or
    ``tx.folder(final)``; when the block ends normally every output is moved into place at once.
    On an exception (including KeyboardInterrupt, and SIGTERM, which is turned into
    ``Terminated`` while the block runs if no other handler is installed) the temporaries are
    removed and nothing at the final names changes. OSErrors name the final paths.
    """
    tx = OutputTransaction()
    restore = None
    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
        restore = signal.signal(signal.SIGTERM, raise_terminated)
    try:
        yield tx
        raise_if_signalled()  # a signal whose exception a library swallowed still cancels the outputs
        tx.commit()
    except OSError as exc:
        if exc.filename is None and exc.errno is not None and tx.staged:
            # write() errors (a full disk) name no file: name the outputs being written
            finals = ", ".join(str(s.final) for s in tx.staged)
            raise OSError(exc.errno, f"{exc.strerror} (while writing {finals})") from None
        raise _renamed(exc, tx.names()) from None
    finally:
        if not tx.committed:
            tx.rollback()
        if restore is not None:
            signal.signal(signal.SIGTERM, restore)


def raise_terminated(signum: int, frame: object) -> None:
    """Signal handler: SIGTERM -> ``Terminated``."""
    raise Terminated(f"terminated by signal {signum}")


# ----------------------------------------------------------------------------------------------
# the command line's signals: one exception, in the main process only
_SIGNALS = (signal.SIGINT, signal.SIGTERM)
_received: list[int] = []  # the first SIGINT / SIGTERM since install_signal_handlers (at most one)
_installed: dict[int, object] = {}  # signal -> the handler it replaced, while ours are installed
_held: list[int] = []  # a signal held in _HOLD_IN code, taken up again by _on_alarm


def interruption(signum: int) -> KeyboardInterrupt:
    """The exception a signal becomes: KeyboardInterrupt for SIGINT, Terminated for SIGTERM."""
    return Terminated(f"terminated by signal {signum}") if signum == signal.SIGTERM else KeyboardInterrupt()


# Code an exception must not be raised into: numba's dispatcher and compiler and llvmlite (Python
# called back from C through ctypes: an exception there left LLVM with a bad pointer, SIGSEGV, or
# a SystemError), and the start of a worker process (a process started but not yet registered
# with its pool would be left running). A signal arriving there is taken up again a moment later
# (SIGALRM, _on_alarm).
_HOLD_IN = ("numba", "llvmlite", "multiprocessing.popen_forkserver", "multiprocessing.forkserver",
            "multiprocessing.process", "multiprocessing.context", "concurrent.futures.process")
_RETRY_S = 0.02


def _held_in(frame: Any) -> bool:
    """Whether the main thread's stack at ``frame`` runs code of _HOLD_IN."""
    while frame is not None:
        name = frame.f_globals.get("__name__", "") or ""
        if name.startswith(_HOLD_IN):
            return True
        frame = frame.f_back
    return False


def _on_alarm(signum: int, frame: Any) -> None:
    """SIGALRM of the retry timer: the held signal's turn again (held again while still in
    _HOLD_IN). A timer signal, not a thread: a handler must not take locks the interrupted code
    may hold (starting a thread inside threading's own code deadlocked)."""
    if _held and not _received:
        _on_signal(_held[0], frame)


def _on_signal(signum: int, frame: Any) -> None:
    """The first SIGINT or SIGTERM raises its ``interruption`` where the main thread is (outside
    _HOLD_IN: there it is taken up again in _RETRY_S s); later ones are ignored (the cleanup the
    first started is not interrupted)."""
    if _received:
        return
    if _held_in(frame):
        if not _held:
            _held.append(signum)  # an error it causes meanwhile (a worker gone) is still this signal's
        signal.setitimer(signal.ITIMER_REAL, _RETRY_S)
        return
    _received.append(signum)
    raise interruption(signum)


def install_signal_handlers() -> bool:
    """SIGINT and SIGTERM raise one exception (``_on_signal``) from now on, even where SIGINT was
    inherited ignored; forget any signal received before. False (nothing done) outside the main
    thread or when installed already."""
    if _installed or threading.current_thread() is not threading.main_thread():
        return False
    _received.clear()
    _held.clear()
    for sig in _SIGNALS:
        _installed[sig] = signal.signal(sig, _on_signal)
    _installed[signal.SIGALRM] = signal.signal(signal.SIGALRM, _on_alarm)
    return True


def restore_signal_handlers() -> None:
    """Put back the handlers ``install_signal_handlers`` replaced."""
    if _installed:
        signal.setitimer(signal.ITIMER_REAL, 0)
    for sig, old in _installed.items():
        signal.signal(sig, old if old is not None else signal.SIG_DFL)
    _installed.clear()


def signal_received() -> int | None:
    """The SIGINT or SIGTERM received since ``install_signal_handlers`` (None: none). A signal
    caught but whose handler has not run yet runs it here (raising its exception)."""
    if not _received and _held:
        _received.append(_held[0])
    return _received[0] if _received else None


def raise_if_signalled() -> None:
    """Raise the interruption of a signal received since ``install_signal_handlers``, also when
    its first exception was swallowed somewhere (a library's broad ``except``)."""
    signum = signal_received()
    if signum is not None:
        raise interruption(signum)
