"""cliutil.atomic: outputs appear whole under their final name, and nothing else is left beside them."""

import os

import pytest

from cliutil.atomic import atomic_path, atomic_paths, staged_folder


def test_linking_a_file_onto_a_name_it_already_has_leaves_no_temporary(tmp_path):
    """POSIX rename of a hard link onto another name of the same file does nothing; the temporary must go."""
    source = tmp_path / "frame.png"
    source.write_bytes(b"pixels")
    for _ in range(2):  # the second run links the same file again
        with atomic_path(tmp_path / "photo.png") as tmp:
            tmp.unlink()
            os.link(source, tmp)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frame.png", "photo.png"]
    assert (tmp_path / "photo.png").read_bytes() == b"pixels"


def test_a_failed_write_leaves_nothing(tmp_path):
    try:
        with atomic_path(tmp_path / "out.txt") as tmp:
            tmp.write_text("half")
            raise RuntimeError("interrupted")
    except RuntimeError:
        pass
    assert list(tmp_path.iterdir()) == []


def test_a_staged_folder_moves_its_files_in_only_on_success(tmp_path):
    """The files written in the staging folder land in the target (replacing same-named ones, keeping others);
    a failure halfway leaves the target as it was and no staging folder beside it."""
    target = tmp_path / "copies"
    target.mkdir()
    (target / "a.jpg").write_bytes(b"old a")
    (target / "kept.jpg").write_bytes(b"kept")
    with pytest.raises(RuntimeError):
        with staged_folder(target) as staging:
            (staging / "a.jpg").write_bytes(b"new a")
            raise RuntimeError("the second photo cannot be edited")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["copies"]
    assert (target / "a.jpg").read_bytes() == b"old a"
    with staged_folder(target) as staging:
        (staging / "a.jpg").write_bytes(b"new a")
        (staging / "b.jpg").write_bytes(b"new b")
        assert not (target / "b.jpg").exists()  # nothing shows before the block ends
    assert {p.name: p.read_bytes() for p in target.iterdir()} == {"a.jpg": b"new a", "b.jpg": b"new b",
                                                                  "kept.jpg": b"kept"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["copies"]


def test_a_staged_folder_makes_a_missing_target(tmp_path):
    with staged_folder(tmp_path / "new" / "copies") as staging:
        (staging / "a.jpg").write_bytes(b"a")
    assert [p.name for p in (tmp_path / "new" / "copies").iterdir()] == ["a.jpg"]


def test_atomic_paths_write_all_or_none(tmp_path):
    """The outputs of one run land together; when a later one cannot be made (a parent that is a file), none is
    written, an older file under one of the names is kept, and the error names the output that failed."""
    (tmp_path / "plan.csv").write_text("old")
    (tmp_path / "file").write_text("x")
    with pytest.raises(NotADirectoryError) as failed:
        with atomic_paths([tmp_path / "plan.csv", tmp_path / "file" / "plot.png"]) as (csv, png):
            csv.write_text("new")
    assert failed.value.filename == str(tmp_path / "file" / "plot.png")
    with pytest.raises(OSError) as failed:
        with atomic_paths([tmp_path / "plan.csv", tmp_path / "plot.png"]) as (csv, png):
            csv.write_text("new")
            raise OSError(28, "No space left on device", str(png))
    assert failed.value.filename == str(tmp_path / "plot.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "plan.csv"]
    assert (tmp_path / "plan.csv").read_text() == "old"
    with atomic_paths([tmp_path / "plan.csv", tmp_path / "plot.png"]) as (csv, png):
        csv.write_text("new")
        png.write_bytes(b"png")
    assert (tmp_path / "plan.csv").read_text() == "new" and (tmp_path / "plot.png").read_bytes() == b"png"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "plan.csv", "plot.png"]
