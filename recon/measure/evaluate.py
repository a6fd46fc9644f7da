"""How real a reconstructed scene looks: render it from the recovered poses and compare with the photos.

The textured scene already holds the photos' lighting, so it is rendered *unlit* (radiance = texture: no sun,
ambient 1, no shadows) with the undistorted pinhole camera of each registered photo, and compared with the
undistorted photo by the paper's formula 3 (``sim.evaluation.realism.photorealism_error_percent``) over the pixels where
the render hits the surface (``covered`` = their fraction; the rest would compare photo content with sky).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pycolmap

from recon.appearance.texture import Photo, load_photos
from sim.render.camera import Rig
from sim.evaluation.realism import photorealism_error_percent
from sim.render.renderer import render
from sim.render.scene import Scene, load_scene
from sim.render.shade import UNLIT


@dataclass(frozen=True)
class PhotoRealism:
    """Formula-3 error (%) of one photo against the render over the covered pixels, and that fraction."""

    name: str
    error_percent: float
    covered: float


def render_unlit(scene: Scene, photo: Photo) -> tuple[np.ndarray, np.ndarray]:
    """The scene seen by ``photo``'s camera and pose, unlit: (H, W, 3) uint8 sRGB and the (H, W) hit mask."""
    view = render(scene, Rig((photo.camera,), (np.eye(4),)), photo.T_world_cam, **UNLIT).views[0]
    return view.rgb, view.valid


def photorealism(scene: Scene, photos: list[Photo]) -> list[PhotoRealism]:
    """Per photo: error of the unlit render against the photo over the pixels that see the surface."""
    results = []
    for photo in photos:
        rgb, valid = render_unlit(scene, photo)
        error = photorealism_error_percent(photo.image[valid], rgb[valid]) if valid.any() else float("nan")
        results.append(PhotoRealism(photo.name, error, float(valid.mean())))
    return results


def scene_photorealism(scene_dir: Path, read_rgb, every: int = 1) -> list[PhotoRealism]:
    """:func:`photorealism` of a recon scene folder against its own undistorted photos (``work/dense``),
    every ``every``-th registered photo."""
    scene_dir = Path(scene_dir)
    model = pycolmap.Reconstruction(scene_dir / "work" / "dense" / "sparse")
    photos = load_photos(model, scene_dir / "work" / "dense" / "images", read_rgb)[::every]
    return photorealism(load_scene(scene_dir), photos)
