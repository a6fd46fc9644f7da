"""A contact sheet of a rendered dataset: left image, right image and colourised depth for a few frames.

One row per chosen frame (spread evenly over the sequence); depth is shown with the turbo colour map
over the 2nd-98th percentile of the finite depths of that frame, sky (``+inf``) in black.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure

from sim.dataset import DatasetError, KittiLayout, read_dataset_json
from cliutil.atomic import atomic_path
from sim.dataset.images import read_exr, read_png
from sim.dataset.kitti import frame_file_name

DEPTH_PERCENTILES = (2.0, 98.0)
ROW_HEIGHT_IN = 2.2


def colourise_depth(depth_m: np.ndarray) -> tuple[np.ndarray, tuple[float, float]]:
    """(H, W, 3) uint8 turbo rendering of a depth map (metres) and the (near, far) range shown; misses black."""
    finite = np.isfinite(depth_m)
    if not finite.any():
        return np.zeros((*depth_m.shape, 3), np.uint8), (0.0, 0.0)
    near, far = np.percentile(depth_m[finite], DEPTH_PERCENTILES)
    scaled = np.clip((depth_m - near) / max(far - near, 1e-6), 0.0, 1.0)
    rgb = (colormaps["turbo"](np.where(finite, scaled, 0.0))[..., :3] * 255).round().astype(np.uint8)
    rgb[~finite] = 0
    return rgb, (float(near), float(far))


def chosen_frames(frame_count: int, rows: int) -> list[int]:
    """Up to ``rows`` frame indices spread evenly from the first to the last frame."""
    return sorted({int(round(i)) for i in np.linspace(0, frame_count - 1, min(rows, frame_count))})


def check_depth_written(formats, dataset: str) -> None:
    """Raise :class:`DatasetError` unless ``formats`` include the depth EXR a contact sheet shows."""
    if "depth_exr" not in formats:
        raise DatasetError(f"{dataset}: a contact sheet shows depth, but the dataset has no depth_exr")


def write_contact_sheet(dataset_dir: Path, out_png: Path, rows: int = 4) -> Path:
    """Write the contact sheet of ``dataset_dir`` to ``out_png`` (atomically). Returns ``out_png``."""
    description = read_dataset_json(Path(dataset_dir))
    check_depth_written(description["formats"], str(dataset_dir))
    layout = KittiLayout(Path(dataset_dir), description["sequence"])
    frames = chosen_frames(int(description["frame_count"]), rows)
    width, height = description["cameras"][0]["width"], description["cameras"][0]["height"]
    figure = Figure(figsize=(3 * ROW_HEIGHT_IN * width / height, ROW_HEIGHT_IN * len(frames)), dpi=100)
    axes = figure.subplots(len(frames), 3, squeeze=False)
    for row, index in zip(axes, frames):
        name = frame_file_name(index, ".png")
        depth, (near, far) = colourise_depth(read_exr(layout.depth_dir(0) / frame_file_name(index, ".exr")))
        panels = ((read_png(layout.colour_dir(0) / name), f"frame {index}: left"),
                  (read_png(layout.colour_dir(1) / name), "right"),
                  (depth, f"depth {near:.0f}-{far:.0f} m (sky black)"))
        for axis, (image, title) in zip(row, panels):
            axis.imshow(image)
            axis.set_title(title, fontsize=8)
            axis.set_axis_off()
    figure.tight_layout()
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out_png) as temporary:
        figure.savefig(temporary, format="png")
    return out_png
