"""Folder outputs and transactions (camsmooth.io.atomic): merge into an existing folder (nested
folders merged, other files kept), whole-folder replace, the folders it refuses to replace and
why, a file or folder in the way, the permissions a plain open()/mkdir() would give, and a
transaction of several outputs installed together -- each checked on the files left on disk."""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

import pytest

from camsmooth.io.atomic import atomic_dir, output_transaction, write_atomic, write_text_atomic


def _tree(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): p.read_text() for p in sorted(folder.rglob("*")) if p.is_file()}


def _leftovers(folder: Path) -> list[str]:
    return [p.name for p in folder.rglob("*") if ".camsmooth-" in p.name]


@pytest.fixture
def umask027():
    old = os.umask(0o027)
    yield
    os.umask(old)


def test_outputs_get_the_modes_of_a_plain_open_and_mkdir(tmp_path, umask027):
    write_text_atomic(tmp_path / "a.txt", "µm ± 1\n")
    assert stat.S_IMODE((tmp_path / "a.txt").stat().st_mode) == 0o640   # 0o666 & ~0o027
    assert (tmp_path / "a.txt").read_bytes() == "µm ± 1\n".encode()
    write_atomic(tmp_path / "b.bin", lambda p: p.write_bytes(b"\x00\x01"))
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"
    with atomic_dir(tmp_path / "rep") as d:   # a new folder
        (d / "x.txt").write_text("x")
        (d / "sub").mkdir()
    assert stat.S_IMODE((tmp_path / "rep").stat().st_mode) == 0o750      # 0o777 & ~0o027
    assert stat.S_IMODE((tmp_path / "rep" / "x.txt").stat().st_mode) == 0o640
    (tmp_path / "rep2").mkdir()
    with atomic_dir(tmp_path / "rep2", replace=True) as d:   # replaced whole
        (d / "y.txt").write_text("y")
    assert stat.S_IMODE((tmp_path / "rep2").stat().st_mode) == 0o750
    with atomic_dir(tmp_path / "rep2") as d:   # merged: a new sub-folder moved in
        (d / "new").mkdir()
        (d / "new" / "z.txt").write_text("z")
    assert stat.S_IMODE((tmp_path / "rep2" / "new").stat().st_mode) == 0o750


def test_merge_keeps_other_files_and_merges_nested_folders(tmp_path):
    out = tmp_path / "out"
    (out / "sub").mkdir(parents=True)
    (out / "keep.txt").write_text("old keep")
    (out / "same.txt").write_text("old same")
    (out / "sub" / "b.txt").write_text("old b")
    with atomic_dir(out) as d:
        (d / "same.txt").write_text("new same")
        (d / "sub").mkdir()
        (d / "sub" / "c.txt").write_text("new c")
        (d / "fresh").mkdir()
        (d / "fresh" / "f.txt").write_text("f")
    assert _tree(out) == {"fresh/f.txt": "f", "keep.txt": "old keep", "same.txt": "new same",
                          "sub/b.txt": "old b", "sub/c.txt": "new c"}
    assert not _leftovers(tmp_path)


def test_replace_swaps_the_whole_folder(tmp_path):
    out = tmp_path / "out"
    (out / "sub").mkdir(parents=True)
    (out / "old.txt").write_text("old")
    (out / "sub" / "b.txt").write_text("b")
    with atomic_dir(out, replace=True) as d:
        (d / "new.txt").write_text("new")
    assert _tree(out) == {"new.txt": "new"}
    assert not _leftovers(tmp_path)


def test_a_file_or_folder_in_the_way_changes_nothing(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "sub").write_text("a file where a folder goes")
    (out / "dir").mkdir()
    (out / "dir" / "inner.txt").write_text("inner")
    before = _tree(out)
    with pytest.raises(NotADirectoryError) as exc:
        with atomic_dir(out) as d:
            (d / "sub").mkdir()
            (d / "sub" / "x.txt").write_text("x")
    assert (exc.value.errno, exc.value.strerror, exc.value.filename) == (
        errno.ENOTDIR, "a file is in the way of a folder to write", str(out / "sub"))
    with pytest.raises(IsADirectoryError) as exc:
        with atomic_dir(out) as d:
            (d / "ok.txt").write_text("ok")
            (d / "dir").write_text("a file where a folder is")
    assert (exc.value.errno, exc.value.strerror, exc.value.filename) == (
        errno.EISDIR, "a folder is in the way of a file to write", str(out / "dir"))
    assert _tree(out) == before and not _leftovers(tmp_path)
    (tmp_path / "plain").write_text("p")
    for replace in (False, True):
        with pytest.raises(NotADirectoryError) as exc:
            with atomic_dir(tmp_path / "plain", replace=replace):
                pass
        assert (exc.value.errno, exc.value.strerror, exc.value.filename) == (
            errno.ENOTDIR, "is a file; a folder is needed here", str(tmp_path / "plain"))
    assert (tmp_path / "plain").read_text() == "p"


def test_folders_never_replaced_whole_and_why(tmp_path, monkeypatch):
    work = tmp_path / "work"
    (work / "inner").mkdir(parents=True)
    home = tmp_path / "home"
    home.mkdir()
    monkeypatch.chdir(work / "inner")
    monkeypatch.setenv("HOME", str(home))
    cases = [(work / "inner", "it is the current folder or holds it"),
             (work, "it is the current folder or holds it"),
             (home, "it is the home folder or the root")]
    for folder, why in cases:
        with pytest.raises(OSError) as exc:
            with atomic_dir(folder, replace=True):
                pass
        assert (exc.value.errno, exc.value.strerror, exc.value.filename) == (
            errno.EPERM, f"will not replace this folder whole ({why})", str(folder))
    out = tmp_path / "out"
    out.mkdir()
    (out / "in.csv").write_text("input")
    with pytest.raises(OSError) as exc:
        with atomic_dir(out, replace=True, keep=[out / "in.csv"]):
            pass
    assert exc.value.strerror == f"will not replace this folder whole (it holds {out / 'in.csv'}, an input or " \
                                 "output of this command)"
    assert (out / "in.csv").read_text() == "input"
    # merging into the current folder is fine
    with atomic_dir(work / "inner") as d:
        (d / "here.txt").write_text("here")
    assert (work / "inner" / "here.txt").read_text() == "here"


def test_a_transaction_installs_every_output_after_a_merged_folder(tmp_path):
    rep = tmp_path / "rep"
    rep.mkdir()
    (rep / "keep.txt").write_text("keep")
    (tmp_path / "r.csv").write_text("old csv")
    with output_transaction() as tx:
        d = tx.folder(rep)
        (d / "plot.txt").write_text("plot")
        tx.file(tmp_path / "r.csv").write_text("new csv")
        tx.file(tmp_path / "new" / "p.nc").write_text("gcode")
    assert _tree(rep) == {"keep.txt": "keep", "plot.txt": "plot"}
    assert (tmp_path / "r.csv").read_text() == "new csv" and (tmp_path / "new" / "p.nc").read_text() == "gcode"
    assert not _leftovers(tmp_path)


def test_a_folder_replaced_whole_may_not_hold_another_output_of_the_command(tmp_path):
    # the folder does not exist when staged; the file output creates it: the commit refuses
    out = tmp_path / "out"
    with pytest.raises(OSError) as exc:
        with output_transaction() as tx:
            tx.folder(out, replace=True)
            tx.file(out / "x.csv").write_text("x")
    assert exc.value.errno == errno.EPERM and exc.value.filename == str(out)
    assert exc.value.strerror == f"will not replace this folder whole (it holds {out / 'x.csv'}, an input or " \
                                 "output of this command)"
    assert not out.exists() and not _leftovers(tmp_path)
    # staged the other way round, refused at once
    out.mkdir()
    with pytest.raises(OSError) as exc:
        with output_transaction() as tx:
            tx.file(out / "y.csv").write_text("y")
            tx.folder(out, replace=True)
    assert exc.value.strerror == f"will not replace this folder whole (it holds {out / 'y.csv'}, an input or " \
                                 "output of this command)"
    assert list(out.iterdir()) == []


def test_staging_folder_inside_an_existing_folder_beside_a_new_one(tmp_path):
    out = tmp_path / "out"
    with atomic_dir(out) as d:   # new: staged beside it, named after it
        assert d.parent == tmp_path and d.name.startswith(".out.camsmooth-")
    out.mkdir(exist_ok=True)
    with atomic_dir(out) as d:   # existing, merged: staged inside it (its parent may not be writable)
        assert d.parent == out and d.name.startswith(".camsmooth-")
    with atomic_dir(out, replace=True) as d:   # replaced whole: beside it
        assert d.parent == tmp_path and d.name.startswith(".out.camsmooth-")
    assert not _leftovers(tmp_path)
    # a folder output in folders that do not exist yet: they are removed again when the block fails
    with pytest.raises(RuntimeError):
        with atomic_dir(tmp_path / "new" / "deep" / "rep") as d:
            (d / "x.txt").write_text("x")
            raise RuntimeError("stop")
    assert not (tmp_path / "new").exists()
    # where no file can be created at all (/proc): say so, naming the output
    with pytest.raises(OSError) as exc:
        with atomic_dir(Path("/proc") / "camsmooth-report"):
            pass
    assert (exc.value.errno, exc.value.strerror, exc.value.filename) == (
        errno.ENOENT, "cannot create files in this folder", "/proc/camsmooth-report")
    # a path that is only an input is not a reason to refuse
    (tmp_path / "rep").mkdir()
    with atomic_dir(tmp_path / "rep", replace=True, keep=[tmp_path / "elsewhere.csv"]) as d:
        (d / "r.txt").write_text("r")
    assert _tree(tmp_path / "rep") == {"r.txt": "r"}


def test_merge_continues_after_a_nested_folder(tmp_path):
    out = tmp_path / "out"
    (out / "a_sub").mkdir(parents=True)
    with atomic_dir(out) as d:
        (d / "a_sub").mkdir()
        (d / "a_sub" / "1.txt").write_text("1")
        (d / "b.txt").write_text("b")
        (d / "c_sub").mkdir()
        (d / "c_sub" / "2.txt").write_text("2")
    assert _tree(out) == {"a_sub/1.txt": "1", "b.txt": "b", "c_sub/2.txt": "2"}


@pytest.mark.parametrize("links", [True, False])
def test_a_failed_commit_restores_every_earlier_output(tmp_path, monkeypatch, links):
    import camsmooth.io.atomic as atomic

    old = tmp_path / "old.csv"
    old.write_text("old csv")
    rep = tmp_path / "rep"
    rep.mkdir()
    (rep / "old.txt").write_text("old report")
    if not links:   # a file system without hard links: the old version is kept as a copy
        def no_link(*a, **k):
            raise OSError(errno.EPERM, "Operation not permitted")
        monkeypatch.setattr(atomic.os, "link", no_link)
    real_replace = os.replace

    def failing_replace(src, dst, *a, **k):
        if Path(dst).name == "last.nc":
            raise OSError(errno.ENOSPC, "No space left on device", str(src), None, str(dst))
        return real_replace(src, dst, *a, **k)

    monkeypatch.setattr(atomic.os, "replace", failing_replace)
    with pytest.raises(OSError) as exc:
        with output_transaction() as tx:
            tx.file(old).write_text("new csv")
            d = tx.folder(rep, replace=True)
            (d / "new.txt").write_text("new report")
            tx.file(tmp_path / "last.nc").write_text("gcode")
    # the error names the user's file, not a temporary
    assert exc.value.errno == errno.ENOSPC and exc.value.filename2 == str(tmp_path / "last.nc")
    assert ".camsmooth-" not in str(exc.value.filename)
    assert old.read_text() == "old csv" and _tree(rep) == {"old.txt": "old report"}
    assert not (tmp_path / "last.nc").exists() and not _leftovers(tmp_path)


def test_an_output_turned_into_a_folder_before_the_move_is_named_with_the_users_path(tmp_path):
    target = tmp_path / "r.csv"
    with pytest.raises(IsADirectoryError) as exc:
        with output_transaction() as tx:
            tx.file(target).write_text("x")
            target.mkdir()   # something else made a folder there meanwhile
            (target / "inside.txt").write_text("i")
    assert exc.value.filename == str(target) and ".camsmooth-" not in str(exc.value)
    assert (target / "inside.txt").read_text() == "i" and not _leftovers(tmp_path)


def test_temporaries_and_refusals_of_single_files(tmp_path):
    from camsmooth.io.atomic import atomic_path

    target = tmp_path / "r.csv"
    with atomic_path(target) as tmp:   # beside the output, hidden, named after it, same suffix
        assert tmp.parent == tmp_path and tmp.name.startswith(".r.csv.camsmooth-") and tmp.suffix == ".csv"
        tmp.write_text("x")
    with atomic_path(target, suffix=".part") as tmp:
        assert tmp.name.endswith(".part")
        tmp.write_text("y")
    assert target.read_text() == "y"
    (tmp_path / "folder").mkdir()
    with pytest.raises(IsADirectoryError) as exc:
        with atomic_path(tmp_path / "folder"):
            pass
    assert (exc.value.errno, exc.value.strerror, exc.value.filename) == (
        errno.EISDIR, "is a folder; a file name is needed here", str(tmp_path / "folder"))
    with pytest.raises(OSError) as exc:
        with atomic_path("/proc/camsmooth.csv"):
            pass
    assert (exc.value.errno, exc.value.strerror, exc.value.filename) == (
        errno.ENOENT, "cannot create files in this folder", "/proc/camsmooth.csv")
    with pytest.raises(OSError) as exc:
        with output_transaction() as tx:
            tx.file(target)
            tx.file(tmp_path / "folder" / ".." / "r.csv")   # the same file by another spelling
    assert (exc.value.errno, exc.value.strerror, exc.value.filename) == (
        errno.EEXIST, "named twice as an output of this command", str(tmp_path / "folder" / ".." / "r.csv"))
    assert target.read_text() == "y" and not _leftovers(tmp_path)


def test_a_file_appearing_where_a_replaced_folder_goes_is_refused_at_commit(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(NotADirectoryError) as exc:
        with output_transaction() as tx:
            d = tx.folder(out, replace=True)
            (d / "x.txt").write_text("x")
            out.write_text("a file made meanwhile")
    assert (exc.value.errno, exc.value.strerror, exc.value.filename) == (
        errno.ENOTDIR, "is a file; a folder is needed here", str(out))
    assert out.read_text() == "a file made meanwhile" and not _leftovers(tmp_path)
