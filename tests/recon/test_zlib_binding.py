"""pycolmap 4.2 exports the zlib it is built with; where it loads the system's libz.so.1 first, OpenCV's next PNG write
aborts the process ("free(): invalid pointer"). Importing ``recon`` binds libz to itself first (recon/__init__.py), so
a script that imports any part of recon and then pycolmap writes PNGs safely. Each case runs in a fresh interpreter:
the order of the very first imports is what matters."""

import subprocess
import sys

import cv2
import numpy as np
import pytest

WRITE_PNG = ("import cv2, numpy as np; image = np.arange(48 * 64 * 3, dtype=np.uint8).reshape(48, 64, 3); "
             "assert cv2.imwrite({path!r}, image); print('written')")


@pytest.mark.parametrize("first", ["recon", "recon.sfm.progress", "recon.cli"])
def test_opencv_writes_a_png_after_recon_then_pycolmap(first, tmp_path):
    path = tmp_path / "image.png"
    script = f"import {first}; import pycolmap; " + WRITE_PNG.format(path=str(path))
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and result.stdout.strip() == "written", result.stderr[-2000:]
    expected = np.arange(48 * 64 * 3, dtype=np.uint8).reshape(48, 64, 3)
    np.testing.assert_array_equal(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), expected)
