"""Pixel encodings of the dataset: PNG (8-bit colour/grey, 16-bit KITTI/VKITTI) and float32 EXR.

Conventions (see docs/dataset-format.md):

* depth is planar z in metres (OpenCV camera z), float32, ``+inf`` where the ray hit nothing;
* disparity in pixels is ``fx * B / z`` for a rectified pair with baseline ``B`` metres
  (exactly 0 where depth is ``+inf``);
* KITTI disparity PNG: uint16 ``round(d * 256)``, 0 = invalid, valid values clipped to
  ``[1, 65535]`` so that a valid pixel never reads as invalid;
* KITTI depth PNG (depth completion/prediction): uint16 ``round(z * 256)``, 0 = invalid (a miss, or beyond
  65535 / 256 = 255.996 m, which it cannot store);
* VKITTI-style depth PNG: uint16 centimetres ``round(z * 100)``, clipped to 65535 (655.35 m),
  which is also the value of a miss (VKITTI2 stores the sky that way);
* normal EXR: unit normals in the camera frame (OpenCV axes), camera x, y, z in the channels ``R``, ``G``, ``B``
  (0, 0, 0 where nothing was hit); class and instance images are grey uint8 / uint16 PNGs.

PNGs are encoded by OpenCV with its default parameters (fast, deterministic); EXRs hold lossless float32 with ZIP
compression: one channel named ``Y`` (depth, disparity), the layout OpenCV 4.x reads as a 2-D float32 image, or the
three channels ``R, G, B`` (normals), which OpenEXR reads as an (H, W, 3) array in R, G, B order and OpenCV as an
(H, W, 3) float32 image in its B, G, R order.
"""

from __future__ import annotations

import io
from pathlib import Path

import cv2
import numpy as np
import OpenEXR
from PIL import Image

from cliutil.atomic import atomic_path, write_bytes_atomic, write_failed

EXR_CHANNEL = "Y"
#: What OpenEXR's Python package calls the R, G, B channels of a file, read or written as one (H, W, 3) array.
EXR_RGB = "RGB"
KITTI_DISPARITY_SCALE = 256.0
KITTI_DEPTH_SCALE = 256.0
#: JPEG quality of Virtual KITTI 2-style colour images (that layout names them ``.jpg``).
JPEG_QUALITY = 95
VKITTI_DEPTH_SCALE = 100.0
UINT16_MAX = 65535


def _check_image(image: np.ndarray, what: str) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype not in (np.uint8, np.uint16) or image.ndim not in (2, 3):
        raise ValueError(f"{what}: expected an (H, W) or (H, W, 3) uint8/uint16 array, got {image.dtype} {image.shape}")
    if image.ndim == 3 and image.shape[2] != 3:
        raise ValueError(f"{what}: expected 3 colour channels, got shape {image.shape}")
    return image


#: zlib's "filtered" strategy for 16-bit maps (disparity, depth): on rendered frames 2.2x faster than
#: OpenCV's default and 2.8x smaller (smooth values); 8-bit images gain nothing from it.
_PNG16_PARAMS = [cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_FILTERED]


def encode_png(image: np.ndarray) -> bytes:
    """PNG bytes of an (H, W) grey or (H, W, 3) **RGB** uint8/uint16 image (lossless)."""
    image = _check_image(image, "PNG image")
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    ok, buffer = cv2.imencode(".png", image, _PNG16_PARAMS if image.dtype == np.uint16 else [])
    if not ok:
        raise RuntimeError(f"OpenCV could not encode a {image.dtype} {image.shape} image as PNG")
    return buffer.tobytes()


def write_png(path: Path, image: np.ndarray) -> None:
    """Encode ``image`` (RGB or grey) as PNG and write it atomically."""
    write_bytes_atomic(path, encode_png(image))


def read_png(path: Path) -> np.ndarray:
    """Read a PNG written by :func:`write_png` back as RGB (or grey / uint16) with its stored dtype."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise ValueError(f"{path}: not a readable image")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB) if image.ndim == 3 else image


def write_jpeg(path: Path, rgb: np.ndarray, quality: int = JPEG_QUALITY) -> None:
    """Encode an (H, W, 3) uint8 **RGB** image as JPEG (OpenCV, deterministic; full-resolution colour, no 4:2:0
    chroma subsampling, which blurs colour edges) and write it atomically."""
    rgb = _check_image(rgb, "JPEG image")
    params = [cv2.IMWRITE_JPEG_QUALITY, quality, cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444]
    ok, buffer = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), params)
    if not ok:
        raise RuntimeError(f"OpenCV could not encode a {rgb.dtype} {rgb.shape} image as JPEG")
    write_bytes_atomic(path, buffer.tobytes())


def rgb_to_grey(rgb: np.ndarray) -> np.ndarray:
    """ITU-R BT.601 luma of an (H, W, 3) uint8 RGB image, as OpenCV computes it (uint8)."""
    return cv2.cvtColor(_check_image(rgb, "RGB image"), cv2.COLOR_RGB2GRAY)


def write_exr(path: Path, values: np.ndarray) -> None:
    """Write an (H, W) array as a lossless float32 EXR, single channel ``Y``, or an (H, W, 3) array as the channels
    ``R, G, B`` (in the order of its last axis); ZIP compression, atomically.

    OpenEXR reports a failed write (a full disk) as a ``RuntimeError``: it is raised as an ``OSError`` naming
    ``path``."""
    values = np.ascontiguousarray(values, dtype=np.float32)
    if values.ndim == 2:
        channels = {EXR_CHANNEL: values}
    elif values.ndim == 3 and values.shape[2] == 3:
        channels = {EXR_RGB: values}
    else:
        raise ValueError(f"{path}: EXR writer expects an (H, W) or (H, W, 3) array, got shape {values.shape}")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_path(path) as temporary, OpenEXR.File(header, channels) as exr:
        try:
            exr.write(str(temporary))
        except RuntimeError as error:
            raise write_failed(path, str(error)) from error


def _open_exr(path: Path, header_only: bool = False) -> OpenEXR.File:
    """An EXR opened (pixels read too unless ``header_only``); ``ValueError`` naming ``path`` if it is missing or not
    a readable EXR (OpenEXR says so with a ``RuntimeError``)."""
    try:
        return OpenEXR.File(str(path), header_only=header_only)
    except RuntimeError as error:
        raise ValueError(f"{path}: not a readable EXR ({error})") from None


def exr_size(path: Path) -> tuple[int, int]:
    """``(width, height)`` in pixels of an EXR's data window, from its header alone (microseconds a file)."""
    with _open_exr(path, header_only=True) as exr:
        low, high = exr.header()["dataWindow"]
    return int(high[0] - low[0] + 1), int(high[1] - low[1] + 1)


def read_exr(path: Path, channel: str = EXR_CHANNEL) -> np.ndarray:
    """Read the ``Y`` channel of an EXR as a float32 (H, W) array, or with ``channel=EXR_RGB`` its ``R, G, B``
    channels as an (H, W, 3) array; ``ValueError`` naming ``path`` if it is missing, not a readable EXR, or without
    that channel."""
    with _open_exr(path) as exr:
        channels = exr.channels()
        if channel not in channels:
            raise ValueError(f"{path}: EXR has channels {sorted(channels)}, expected {channel!r}")
        return np.asarray(channels[channel].pixels, dtype=np.float32)


def disparity_from_depth(depth_m: np.ndarray, fx_px: float, baseline_m: float) -> np.ndarray:
    """Disparity in pixels ``fx * B / z`` from planar depth (0 where depth is ``+inf``), float32."""
    depth_m = np.asarray(depth_m, dtype=np.float64)
    with np.errstate(divide="ignore"):
        disparity = fx_px * baseline_m / depth_m
    return disparity.astype(np.float32)


def kitti_disparity_png(disparity_px: np.ndarray) -> np.ndarray:
    """KITTI 16-bit disparity ``round(d * 256)``: 0 where invalid (d <= 0, not finite), valid clipped to [1, 65535]."""
    disparity_px = np.asarray(disparity_px, dtype=np.float64)
    valid = np.isfinite(disparity_px) & (disparity_px > 0)
    return _kitti_uint16(disparity_px * KITTI_DISPARITY_SCALE, valid)


def kitti_depth_png(depth_m: np.ndarray) -> np.ndarray:
    """KITTI 16-bit depth ``round(z * 256)`` (metres): 0 where invalid (a miss, z <= 0, or too far for 16 bits,
    z > 255.996 m), valid values at least 1 so that no valid pixel reads as invalid."""
    scaled = np.asarray(depth_m, dtype=np.float64) * KITTI_DEPTH_SCALE
    return _kitti_uint16(scaled, np.isfinite(scaled) & (scaled > 0) & (np.rint(scaled) <= UINT16_MAX))


def _kitti_uint16(scaled: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``round(scaled)`` as uint16 where ``valid`` (clipped to [1, 65535]), 0 elsewhere."""
    values = np.clip(np.rint(np.where(valid, scaled, 0.0)), 1, UINT16_MAX)
    return np.where(valid, values, 0).astype(np.uint16)


def vkitti_depth_png(depth_m: np.ndarray) -> np.ndarray:
    """VKITTI-style 16-bit depth in centimetres, clipped to 65535 (655.35 m, also the value of a miss)."""
    depth_m = np.asarray(depth_m, dtype=np.float64)
    centimetres = np.where(np.isfinite(depth_m), depth_m * VKITTI_DEPTH_SCALE, UINT16_MAX)
    return np.clip(np.rint(centimetres), 0, UINT16_MAX).astype(np.uint16)


def write_palette_png(path: Path, indices: np.ndarray, palette: np.ndarray) -> None:
    """Write an (H, W) uint8 array of palette indices as an 8-bit indexed (palette) PNG, atomically; ``palette`` is
    (N <= 256, 3) uint8 RGB, the colour of each index. Pillow writes it (OpenCV writes no palette PNGs); PIL reads
    the indices back (``np.asarray(Image.open(path))``), OpenCV the colours."""
    indices = np.ascontiguousarray(indices)
    if indices.dtype != np.uint8 or indices.ndim != 2:
        raise ValueError(f"{path}: palette PNG expects an (H, W) uint8 array, got {indices.dtype} {indices.shape}")
    image = Image.frombytes("P", (indices.shape[1], indices.shape[0]), indices.tobytes())
    image.putpalette(np.asarray(palette, dtype=np.uint8).ravel().tolist())
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")
    write_bytes_atomic(path, buffer.getvalue())
