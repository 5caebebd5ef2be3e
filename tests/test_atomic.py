"""camsmooth.io.atomic: files, report folders (written into, never deleting other files) and the
all-or-nothing transaction of a command's outputs, including failures during the commit and
signals."""

from __future__ import annotations

import errno
import os
import signal
from pathlib import Path

import pytest

from camsmooth.io import atomic
from camsmooth.io.atomic import Terminated, atomic_dir, atomic_path, output_transaction, write_text_atomic


def listing(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): (p.read_text() if p.is_file() else "/") for p in sorted(folder.rglob("*"))}


def test_atomic_path_replaces_or_leaves_untouched(tmp_path):
    f = tmp_path / "a.txt"
    write_text_atomic(f, "one")
    with pytest.raises(RuntimeError):
        with atomic_path(f) as tmp:
            tmp.write_text("partial")
            raise RuntimeError("boom")
    assert listing(tmp_path) == {"a.txt": "one"}
    write_text_atomic(f, "two")
    assert listing(tmp_path) == {"a.txt": "two"}


def test_atomic_path_errors_name_the_users_path(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(IsADirectoryError) as e:
        write_text_atomic(tmp_path / "d", "x")
    assert e.value.filename == str(tmp_path / "d")
    (tmp_path / "f").write_text("file")
    with pytest.raises(NotADirectoryError) as e:
        write_text_atomic(tmp_path / "f" / "sub" / "x.txt", "x")
    assert e.value.filename == str(tmp_path / "f")
    with pytest.raises(OSError) as e:
        with atomic_path(tmp_path / "out.csv") as tmp:
            raise OSError(errno.ENOSPC, "No space left on device", str(tmp))
    assert e.value.errno == errno.ENOSPC and e.value.filename == str(tmp_path / "out.csv")
    assert listing(tmp_path) == {"d": "/", "f": "file"}


def test_atomic_path_creates_missing_folders(tmp_path):
    write_text_atomic(tmp_path / "a" / "b" / "c.txt", "x")
    assert (tmp_path / "a" / "b" / "c.txt").read_text() == "x"


def test_atomic_dir_writes_into_an_existing_folder(tmp_path):
    rep = tmp_path / "rep"
    rep.mkdir()
    (rep / "mine.txt").write_text("user")
    (rep / "report.html").write_text("old")
    with atomic_dir(rep) as tmp:
        (tmp / "report.html").write_text("new")
        (tmp / "plot.png").write_text("png")
    assert listing(rep) == {"mine.txt": "user", "plot.png": "png", "report.html": "new"}
    with pytest.raises(RuntimeError):
        with atomic_dir(rep) as tmp:
            (tmp / "report.html").write_text("newer")
            raise RuntimeError
    assert listing(rep) == {"mine.txt": "user", "plot.png": "png", "report.html": "new"}


def test_atomic_dir_into_the_current_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "input.csv").write_text("data")
    with atomic_dir(".") as tmp:
        (tmp / "report.html").write_text("r")
    assert listing(tmp_path) == {"input.csv": "data", "report.html": "r"}


def test_atomic_dir_refuses_a_folder_where_a_file_goes(tmp_path):
    rep = tmp_path / "rep"
    (rep / "report.html").mkdir(parents=True)
    (rep / "a.png").write_text("old")
    with pytest.raises(IsADirectoryError) as e:
        with atomic_dir(rep) as tmp:
            (tmp / "a.png").write_text("new")
            (tmp / "report.html").write_text("new")
    assert e.value.filename == str(rep / "report.html")
    assert listing(rep) == {"a.png": "old", "report.html": "/"}  # nothing moved


def test_atomic_dir_replace_swaps_the_whole_folder(tmp_path):
    rep = tmp_path / "rep"
    rep.mkdir()
    (rep / "mine.txt").write_text("user")
    with atomic_dir(rep, replace=True) as tmp:
        (tmp / "report.html").write_text("new")
    assert listing(tmp_path) == {"rep": "/", "rep/report.html": "new"}


@pytest.mark.parametrize("target", [".", "..", "~"])
def test_atomic_dir_replace_refuses_current_parent_home(tmp_path, monkeypatch, target):
    # a sandbox: the current folder two levels down, HOME inside tmp_path (a failure here must not
    # be able to remove anything outside tmp_path)
    cwd, home = tmp_path / "a" / "b", tmp_path / "home"
    cwd.mkdir(parents=True)
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.chdir(cwd)
    for d in (cwd, home):
        (d / "x.txt").write_text("x")
    before = listing(tmp_path)
    with pytest.raises(OSError, match="will not replace"):
        with atomic_dir(os.path.expanduser(target), replace=True) as tmp:
            (tmp / "report.html").write_text("new")
    assert listing(tmp_path) == before


def test_atomic_dir_replace_refuses_a_folder_holding_a_kept_path(tmp_path):
    (tmp_path / "rep").mkdir()
    (tmp_path / "rep" / "in.csv").write_text("input")
    with pytest.raises(OSError, match="in.csv"):
        with atomic_dir(tmp_path / "rep", replace=True, keep=[tmp_path / "rep" / "in.csv"]):
            pass
    assert (tmp_path / "rep" / "in.csv").read_text() == "input"


def test_atomic_dir_on_a_file_is_refused(tmp_path):
    (tmp_path / "rep").write_text("a file")
    with pytest.raises(NotADirectoryError):
        with atomic_dir(tmp_path / "rep"):
            pass
    assert listing(tmp_path) == {"rep": "a file"}


def _stage_three(tx, root: Path) -> None:
    tx.file(root / "a.csv").write_text("A2")
    tx.file(root / "new" / "deep" / "b.nc").write_text("B2")
    rep = tx.folder(root / "rep")
    (rep / "report.html").write_text("R2")


def test_transaction_moves_everything_at_the_end(tmp_path):
    (tmp_path / "a.csv").write_text("A1")
    with output_transaction() as tx:
        _stage_three(tx, tmp_path)
        assert listing(tmp_path).get("a.csv") == "A1" and "rep" not in listing(tmp_path)
    assert listing(tmp_path) == {"a.csv": "A2", "new": "/", "new/deep": "/", "new/deep/b.nc": "B2", "rep": "/",
                                 "rep/report.html": "R2"}


def test_transaction_error_leaves_nothing(tmp_path):
    (tmp_path / "a.csv").write_text("A1")
    with pytest.raises(ValueError):
        with output_transaction() as tx:
            _stage_three(tx, tmp_path)
            raise ValueError("failed after writing")
    assert listing(tmp_path) == {"a.csv": "A1"}  # the folders made for b.nc are gone too


def test_transaction_failure_during_commit_restores_the_old_files(tmp_path, monkeypatch):
    (tmp_path / "a.csv").write_text("A1")
    (tmp_path / "rep").mkdir()
    (tmp_path / "rep" / "report.html").write_text("R1")
    real = os.replace
    calls = []

    def flaky(src, dst):
        calls.append(dst)
        if len(calls) == 3:  # a.csv, b.nc in place; the report's file fails
            raise OSError(errno.EIO, "Input/output error", str(src))
        return real(src, dst)

    monkeypatch.setattr(atomic.os, "replace", flaky)
    with pytest.raises(OSError) as e:
        with output_transaction() as tx:
            _stage_three(tx, tmp_path)
    monkeypatch.setattr(atomic.os, "replace", real)
    assert e.value.errno == errno.EIO and ".camsmooth-" not in str(e.value.filename)
    assert listing(tmp_path) == {"a.csv": "A1", "rep": "/", "rep/report.html": "R1"}


def test_write_error_without_a_file_name_names_the_outputs(tmp_path):
    with pytest.raises(OSError) as e:
        with output_transaction() as tx:
            tx.file(tmp_path / "a.csv")
            raise OSError(errno.ENOSPC, "No space left on device")
    assert str(tmp_path / "a.csv") in e.value.strerror
    assert listing(tmp_path) == {}


def test_errors_inside_a_staged_folder_name_the_final_folder(tmp_path):
    with pytest.raises(OSError) as e:
        with output_transaction() as tx:
            rep = tx.folder(tmp_path / "rep")
            raise OSError(errno.ENOSPC, "No space left on device", str(rep / "plot.png"))
    assert e.value.filename == str(tmp_path / "rep" / "plot.png")


def test_sigterm_inside_a_transaction_cleans_up_and_restores_the_handler(tmp_path):
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    with pytest.raises(Terminated):
        with output_transaction() as tx:
            tx.file(tmp_path / "a.csv").write_text("A")
            os.kill(os.getpid(), signal.SIGTERM)
            raise AssertionError("the signal should have raised")  # pragma: no cover
    assert listing(tmp_path) == {}
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL


def test_signal_during_the_commit_waits_for_it(tmp_path, monkeypatch):
    """SIGTERM arriving between two renames of the commit is held until all are done."""
    real = os.replace
    sent = []

    def replace_then_signal(src, dst):
        real(src, dst)
        if not sent:
            sent.append(dst)
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(atomic.os, "replace", replace_then_signal)
    with pytest.raises(Terminated):
        with output_transaction() as tx:
            tx.file(tmp_path / "a.csv").write_text("A")
            tx.file(tmp_path / "b.csv").write_text("B")
    assert listing(tmp_path) == {"a.csv": "A", "b.csv": "B"}  # the commit finished whole
