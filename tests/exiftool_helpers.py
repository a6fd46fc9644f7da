"""exiftool (Phil Harvey's, the reference EXIF/XMP reader and writer) run on our files; tests that use it skip,
saying why, where it is not installed (Debian: ``apt-get install libimage-exiftool-perl``)."""

from __future__ import annotations

import shutil
import subprocess

import pytest

EXIFTOOL = shutil.which("exiftool")
needs_exiftool = pytest.mark.skipif(EXIFTOOL is None, reason="exiftool is not installed "
                                                             "(Debian/Ubuntu: apt-get install libimage-exiftool-perl)")


def exiftool(*args, binary: bool = False) -> str | bytes:
    """exiftool's stdout for ``args`` (paths or options), as bytes if ``binary``; the test fails with its stderr
    if it fails."""
    done = subprocess.run([EXIFTOOL, *map(str, args)], capture_output=True, text=not binary, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


def serious_warnings(path) -> list[str]:
    """The warnings of ``exiftool -validate`` on a file that are not marked ``[minor]``."""
    lines = exiftool("-validate", "-warning", "-a", "-s3", path).splitlines()
    return [line for line in lines[1:] if not line.startswith("[minor]")]  # line 0: the summary ("OK", "N Warnings")
