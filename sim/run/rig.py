"""The rig of a dataset render: its cameras from :class:`~sim.run.options.RigOptions`, or the scene's own lenses when
a replay renders each photo through its lens."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from sim.dataset import needs_disparity
from sim.render.camera import PinholeCamera, Rig
from sim.render.scene import Scene
from sim.run.options import DEFAULT_SIZE, RenderInputError, RigOptions


def build_rig(rig: RigOptions, camera: PinholeCamera | None = None) -> Rig:
    """``cameras`` identical cameras in a row, camera k at ``k * baseline`` along camera x: ``camera``, or a
    pinhole of the options' size, field of view and distortion."""
    if camera is None:
        width, height = rig.width or DEFAULT_SIZE[0], rig.height or DEFAULT_SIZE[1]
        camera = PinholeCamera.from_fov(width, height, rig.fov_deg, dist=rig.distortion)
    offsets = [np.eye(4) for _ in range(rig.cameras)]
    for k, T in enumerate(offsets):
        T[0, 3] = k * rig.baseline_m
    return Rig(tuple([camera] * rig.cameras), tuple(offsets))


def replay_lenses(scene: Scene, rig: RigOptions, formats: Sequence[str]) -> list[PinholeCamera]:
    """The lens of each of the scene's cameras as replayed: its own, or scaled to ``rig.width``.

    :class:`RenderInputError` when the scene has no cameras, when they differ in image size (a dataset has one
    size; give ``--width``) or when they have lens distortion and ``formats`` ask for disparity.
    """
    if not scene.cameras:
        raise RenderInputError(f"{scene.source}: replay needs --geotags FILE, or a reconstructed scene whose "
                               "scene.json names its cameras.json")
    lenses = [c.camera.scaled(rig.width) if rig.width else c.camera for c in scene.cameras]
    sizes = {lens.shape: c.name for lens, c in zip(lenses, scene.cameras)}
    if len(sizes) > 1:
        shown = ", ".join(f"{name} {w}x{h}" for (h, w), name in sizes.items())
        raise RenderInputError(f"{scene.source}: the scene's cameras differ in image size ({shown}); a dataset has "
                               "one size: give --width, or replay photos of one camera")
    if any(lens.dist for lens in lenses) and needs_disparity(formats):
        raise RenderInputError("disparity needs rectified (undistorted) images and the scene's cameras have lens "
                               "distortion: choose --formats without disparity_* (e.g. depth_exr)")
    return lenses
