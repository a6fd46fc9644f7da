"""cliutil.atomic: outputs appear whole under their final name, and nothing else is left beside them."""

import os

from cliutil.atomic import atomic_path


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
