"""One dataset frame from its index: the rig, the pose source per mode, the light, the renderer, the camera effects.

:class:`FrameRenderer` loads the scene and builds embree once, then turns frame ``i`` into a
:class:`~sim.dataset.FrameRecord`. The pose, the random sun and the anti-aliasing jitter of frame ``i`` come from
generators seeded by ``(seed, i)`` only (sim/sampling/seeds.py), so the bytes of a frame do not depend on which
process renders it, in which order, or in which shard.
"""

from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from sim.dataset import FrameRecord
from sim.dataset.async_writer import MAX_PENDING_FRAMES
from sim.dataset.writer import LABEL_FORMATS, camera_description, needs_labels, view_arrays
from sim.drone.exposure import AUTO_EXPOSURE_WINDOW_S, auto_exposure_gain, metered_luminance
from sim.motion.shutter import render_in_time
from sim.render.camera import Rig
from sim.render.color import SRGB8_TO_LINEAR
from sim.render.film import apply_photometric, effects_memory_bytes
from sim.render.provenance import provenance_image
from sim.render.raycast import default_workers
from sim.render.renderer import View, render, render_memory_bytes
from sim.render.scene import Scene, SceneError, load_scene
from sim.run.options import RenderInputError, RenderOptions
from sim.run.poses import PoseSource
from sim.run.rig import build_rig, replay_lenses
from sim.sampling.light import FrameLight, frame_light
from sim.sampling.pose import PoseSample
from sim.sampling.seeds import EXPOSURE_STREAM, NOISE_STREAM, RENDER_STREAM, frame_rng

#: Width (pixels) of the small render on which auto-exposure meters a view.
METERING_WIDTH = 64


@dataclass(frozen=True)
class ViewImages:
    """What the dataset keeps of a rendered view: ``rgb`` (H, W, 3) uint8, planar ``depth`` (H, W) float32 m, and
    only when the formats ask for them (None otherwise, so queued frames stay small): ``normal`` (H, W, 3) float32
    camera-frame unit normals, ``semantic`` (H, W) uint8 class ids, ``instance`` (H, W) uint16 object ids,
    ``provenance`` (H, W) uint8 face provenance codes (:data:`sim.dataset.writer.VIEW_ARRAYS`). Queued frames hold no ray lengths or triangle indices."""

    rgb: np.ndarray
    depth: np.ndarray
    normal: np.ndarray | None = None
    semantic: np.ndarray | None = None
    instance: np.ndarray | None = None
    provenance: np.ndarray | None = None


@dataclass
class FrameStats:
    """What a worker reports about one rendered frame (sent to the parent for the progress bar)."""

    index: int
    rejected: int
    render_s: float
    done_s: float = math.nan  # seconds from the start of the run until the parent heard of it


def queued_bytes_per_pixel(formats: Sequence[str]) -> int:
    """Bytes per pixel of a view's :class:`ViewImages` for ``formats``: rgb and depth, and each array they add."""
    return 3 + 4 + sum(np.dtype(dtype).itemsize * channels for _, dtype, channels in view_arrays(formats))


def refuse_unlabelled(scene: Scene, scene_dir: Path, formats: Sequence[str]) -> None:
    """:class:`RenderInputError` (one line naming the scene and how to label it) when ``formats`` ask for class or
    object images and the scene has no face labels."""
    if needs_labels(formats) and scene.labels is None:
        asked = ",".join(name for name in formats if name in LABEL_FORMATS)
        raise RenderInputError(f"{scene_dir}: --formats {asked} needs the scene's face labels and its scene.json "
                               f"names none; label a reconstruction with 'aerostereo-recon labels {scene_dir}'")


class FrameRenderer:
    """Renders frames of one dataset: the scene and embree are built once, then :meth:`record` per frame.

    ``threads``: casting threads of this process (all CPUs for one process, fewer when several share them).
    """

    def __init__(self, scene_dir: Path, options: RenderOptions, threads: int | None = None):
        self.options = options
        try:
            self.scene = load_scene(scene_dir, with_labels=needs_labels(options.outputs.formats),
                                    with_provenance="provenance_png" in options.outputs.formats)
        except SceneError as error:
            raise RenderInputError(str(error)) from None
        refuse_unlabelled(self.scene, scene_dir, options.outputs.formats)
        self.lenses = (replay_lenses(self.scene, options.rig, options.outputs.formats)
                       if options.poses.replays_scene_cameras else None)
        self.rig = build_rig(options.rig, self.lenses[0] if self.lenses else None)
        try:
            self.poses = PoseSource(self.scene, options.poses, options.rig, self.rig.cameras[0], options.seed)
        except ValueError as error:
            raise RenderInputError(str(error)) from None
        self.options = options = replace(options, poses=self.poses.options)  # random poses fitted to the scene
        self.sun = options.light.setting(options.poses)
        try:
            self.light(0)
        except ValueError as error:  # the real sun below the horizon
            raise RenderInputError(f"--sun {self.sun.text}: {error}; give a time when it is up there") from None
        self.threads = threads or default_workers()
        self.pool = ThreadPoolExecutor(self.threads)
        self._meterings: dict[int, tuple[float, float]] = {}

    @property
    def frame_count(self) -> int:
        return self.poses.frame_count

    def memory_bytes(self) -> int:
        """Peak memory (bytes) of rendering and writing frames in this process: the render of the largest frame
        plus the frames queued for writing (each view's :class:`ViewImages`: rgb and depth, 7 bytes per pixel, plus
        12 for normals, 1 for classes, 2 for objects, 1 for provenance codes when the formats ask for them), plus the camera effects' images
        when any is on."""
        largest = max(camera.width * camera.height for camera in self.lenses or self.rig.cameras)
        pixels = [largest] * len(self.rig.cameras)
        queued = (MAX_PENDING_FRAMES + 1) * queued_bytes_per_pixel(self.options.outputs.formats) * sum(pixels)
        effects = effects_memory_bytes(pixels) if self.options.effects.enabled else 0
        return render_memory_bytes(pixels, self.options.rig.spp, self.threads) + queued + effects

    def record(self, index: int) -> tuple[FrameRecord, FrameStats]:
        """Render frame ``index`` (its pose, sun and jitter depend only on ``(seed, index)``)."""
        start = time.perf_counter()
        sample = self.poses.pose(index)
        rng = frame_rng(self.options.seed, index, RENDER_STREAM)
        extra = sample.record()
        rig, lighting, sun = self._rig_lighting(index)
        frame = render(self.scene, rig, sample.T_world_cam, samples_per_pixel=self.options.rig.spp, rng=rng,
                       pool=self.pool, **lighting)
        if self.lenses is not None:
            extra["camera"] = camera_description(rig.cameras[0])
        colours = [view.rgb for view in frame.views]
        if self.options.effects.enabled:
            gain = self._auto_exposure_gain(index) if self.options.effects.auto_exposure else None
            if gain is not None:
                extra["auto_exposure_gain"] = gain.tolist()
            colours = self._with_effects(index, sample, frame, rig, lighting, gain)
        elapsed = time.perf_counter() - start
        views = [self._kept(rgb, view) for rgb, view in zip(colours, frame.views)]
        record = FrameRecord(index=index, views=views, T_world_cam=frame.views[0].T_world_cam,
                             time_s=sample.time_s, seed=self.options.seed, sun=sun, extra=extra)
        return record, FrameStats(index, sample.rejected, elapsed)

    def _kept(self, rgb: np.ndarray, view: View) -> ViewImages:
        """What the dataset keeps of ``view`` (its colour ``rgb`` after any camera effect): the arrays its formats
        write. Normals, classes, objects and provenance codes come from the pixel-centre rays of the frame's pose,
        like depth."""
        formats = self.options.outputs.formats
        labels = self.scene.labels
        return ViewImages(rgb, view.depth,
                          normal=view.camera_normal() if "normal_exr" in formats else None,
                          semantic=labels.class_image(view.triangle) if "semantic_png" in formats else None,
                          instance=labels.instance_image(view.triangle) if "instance_png" in formats else None,
                          provenance=(provenance_image(self.scene.face_provenance, view.triangle)
                                      if "provenance_png" in formats else None))

    def light(self, index: int) -> FrameLight:
        """Frame ``index``'s light (:func:`~sim.sampling.light.frame_light`): a trajectory is one flight under one sky,
        frame 0's for every frame; random poses and replays draw their own (the random form)."""
        draw = 0 if self.options.poses.mode == "trajectory" else index
        return frame_light(self.sun, self.options.seed, draw, self.scene.origin)

    def _rig_lighting(self, index: int) -> tuple[Rig, dict, dict | None]:
        """Frame ``index``'s rig (a replay of the scene's cameras: each photo's own lens), the lighting keywords of
        :func:`render` and the record of its sun (:attr:`~sim.sampling.light.FrameLight.frame_record`, None when
        unlit)."""
        light = self.light(index)
        rig = self.rig if self.lenses is None else build_rig(self.options.rig, self.lenses[index])
        return rig, light.keywords, light.frame_record

    def _with_effects(self, index: int, sample: PoseSample, frame, rig: Rig, lighting: dict,
                      gain: np.ndarray | None) -> list[np.ndarray]:
        """The 8-bit colour of every view of ``frame`` with the options' camera effects (:class:`~sim.run.options.CameraEffects`) and the
        auto-exposure ``gain`` per channel (None: off); the frame's depth and pose stay as rendered."""
        effects, seed = self.options.effects, self.options.seed
        if effects.in_time:
            linear = render_in_time(self.scene, rig, self.poses.pose_at, sample.time_s, effects=effects,
                                    samples_per_pixel=self.options.rig.spp, pool=self.pool,
                                    rng=lambda: frame_rng(seed, index, RENDER_STREAM), **lighting)
        else:
            linear = [SRGB8_TO_LINEAR[view.rgb] for view in frame.views]
        noise = frame_rng(seed, index, NOISE_STREAM)
        return [apply_photometric(image, camera, effects, gain, noise) for image, camera in zip(linear, rig.cameras)]

    def _auto_exposure_gain(self, index: int) -> np.ndarray:
        """Frame ``index``'s auto-exposure gain per channel: the virtual drone camera's model
        (:func:`sim.drone.exposure.auto_exposure_gain`) over the frames of the last :data:`AUTO_EXPOSURE_WINDOW_S` up to
        this one, each metered on a small render of its left view."""
        window = [index]
        now = self._metering(index)[0]
        while window[0] > 0 and now - self._metering(window[0] - 1)[0] <= AUTO_EXPOSURE_WINDOW_S:
            window.insert(0, window[0] - 1)
        self._meterings = {k: self._meterings[k] for k in self._meterings if k >= window[0]}
        times, metered = zip(*(self._metering(k) for k in window))
        noise = np.array([frame_rng(self.options.seed, k, EXPOSURE_STREAM).standard_normal(4) for k in window])
        return auto_exposure_gain(times, metered, noise)

    def _metering(self, index: int) -> tuple[float, float]:
        """Frame ``index``'s time (s) and the metered luminance of its left view (a :data:`METERING_WIDTH` render),
        computed once: consecutive frames share most of their auto-exposure windows."""
        if index not in self._meterings:
            sample, (rig, lighting, _) = self.poses.pose(index), self._rig_lighting(index)
            probe = Rig((rig.cameras[0].scaled(METERING_WIDTH),))
            view = render(self.scene, probe, sample.T_world_cam, pool=self.pool, **lighting).views[0]
            self._meterings[index] = (sample.time_s, metered_luminance(SRGB8_TO_LINEAR[view.rgb]))
        return self._meterings[index]

    def close(self) -> None:
        self.pool.shutdown()
