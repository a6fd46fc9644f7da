"""The capture light file of a relightable scene: the light a reconstruction divided out of its texture (linear RGB,
the renderer's units, on the texture's UVs), so that albedo x capture light renders the photos' own lighting.

Stored as a 16-bit RGB PNG, ``value = code / CODES_PER_UNIT`` (0 to 4 in steps of 1/16384: the light of a clear day
is below 3.5 in these units), rows as the texture's image. Any image tool opens it; the numbers are linear, not sRGB.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from cliutil.atomic import atomic_path, write_failed

#: PNG codes per unit of linear light.
CODES_PER_UNIT = 16384
#: How scene.json describes the encoding.
ENCODING = f"16-bit RGB PNG, linear light = code / {CODES_PER_UNIT}"


def write_capture_light(path: Path, light: np.ndarray) -> None:
    """Write a ``(H, W, 3)`` linear capture light as a 16-bit PNG (atomically); values clipped to [0, 65535 / 16384]."""
    light = np.asarray(light, dtype=np.float64)
    if light.ndim != 3 or light.shape[2] != 3 or not np.all(np.isfinite(light)):
        raise ValueError(f"{path}: a capture light is a finite (H, W, 3) image, got shape {light.shape}")
    codes = np.round(np.clip(light, 0.0, 65535 / CODES_PER_UNIT) * CODES_PER_UNIT).astype(np.uint16)
    with atomic_path(path) as temporary:
        if not cv2.imwrite(str(temporary), cv2.cvtColor(codes, cv2.COLOR_RGB2BGR)):
            raise write_failed(path, "OpenCV could not write the PNG")


def read_capture_light(path: Path) -> np.ndarray:
    """The ``(H, W, 3)`` float32 linear capture light of a 16-bit PNG; ``ValueError`` naming ``path`` if it is not
    one."""
    codes = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if codes is None or codes.dtype != np.uint16 or codes.ndim != 3 or codes.shape[2] != 3:
        raise ValueError(f"{path}: not a 16-bit RGB PNG capture light")
    return cv2.cvtColor(codes, cv2.COLOR_BGR2RGB).astype(np.float32) / CODES_PER_UNIT
