"""Render a scene's GLB in Blender Cycles through ``bpy``, which lives in an interpreter of its own.

The ``bpy`` wheels (Blender 5 as a Python module) exist only for the Python version Blender ships and pin numpy < 2,
so ``bpy`` gets its own virtualenv (``python3.11 -m venv .venv-bpy && .venv-bpy/bin/pip install bpy``) and this file
is run by it as a script, on a job written as JSON: one process per job, nothing of ours imported there.

- Our side: :func:`bpy_python` finds the interpreter (``$AEROSTEREO_BPY_PYTHON``, else ``<repo>/.venv-bpy/bin/python``),
  :func:`frame_job` sets a :class:`CyclesJob` up from a dataset frame, :func:`run_cycles` runs one and returns its
  times, :func:`read_depth` reads the depth it wrote.
- Blender's side (``python tools/peers/blender_cycles.py JOB.json`` under that interpreter): imports the GLB as it is
  (Blender turns glTF's +Y up into its +Z up, so its X, Y, Z are our ENU metres), adds the camera at the job's pose
  (OpenCV axes turned into Blender's: x right, y up, looking along -z) with its pinhole intrinsics, the sun and a grey
  world, and renders with the Standard view transform (plain sRGB, as our film) and no dither: an 8-bit sRGB PNG
  and, through the compositor, the planar depth in metres as a one-channel EXR.

The light, as our renderer's (docs/render-engine.md): a Blender sun of Strength ``E`` (irradiance, W/m²) lights a
diffuse surface of albedo ``a`` facing it with radiance ``a * E / pi``, ours with ``a * 0.1 * strength``, so the Blender
Strength of a frame is ``strength * 0.1 * pi`` (``frames.jsonl``'s ``blender_strength``). A uniform world of colour
``L`` lights it with ``a * L * sky visibility``, our ambient sky: ``L`` = 0.3 (an overcast frame: its ``ambient``).
We trace no interreflections and shade no specular light, so the job has Cycles do neither either.
"""

from __future__ import annotations

import functools
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

#: The environment variable naming the interpreter that imports ``bpy``.
BPY_PYTHON_ENV = "AEROSTEREO_BPY_PYTHON"
#: Where the interpreter is looked for when the variable is not set.
REPO_BPY_PYTHON = Path(__file__).resolve().parents[2] / ".venv-bpy" / "bin" / "python"
#: How to make that interpreter (said when it is missing).
BPY_INSTALL = "python3.11 -m venv .venv-bpy && .venv-bpy/bin/pip install bpy"
#: Blender's camera clip distance (metres); Cycles' depth of a pixel that hits nothing is beyond it.
CLIP_END_M = 1e5
#: Cycles' smallest pixel filter (pixels): every sample at the pixel centre, as our renderer's 1 sample per pixel.
PIXEL_CENTRE_FILTER_PX = 0.01


class BpyUnavailable(RuntimeError):
    """No interpreter that imports ``bpy``; the message says why."""


@dataclass(frozen=True)
class CyclesJob:
    """One Cycles render of the GLB ``glb``.

    Camera: pinhole ``fx, fy, cx, cy`` (pixels, square: fx == fy), ``width`` x ``height``, at ``T_world_cam`` (4x4
    camera-to-world, ENU metres, OpenCV camera axes). ``sun``: ``azimuth_deg`` clockwise from north, ``elevation_deg``
    above the horizon (towards the sun), ``blender_strength`` (W/m²), or None for no sun. ``world``: the grey
    background colour (the sky's light; 0 for none). ``samples`` per pixel, ``pixel_filter_px`` the width of Cycles'
    box filter (pixels: 1 is the pixel, as our supersampling; :data:`PIXEL_CENTRE_FILTER_PX` its centre), ``threads``.
    ``our_light_model``: direct light only (Cycles' max bounces 0) on the materials' diffuse part (the glTF importer's
    Principled BSDF with its Specular IOR Level at 0), as our renderer's. The render runs ``1 + repeats`` times (the
    first is a warm-up when ``repeats`` > 0) and writes ``colour_png`` (8-bit sRGB) and ``depth_exr`` (planar depth,
    metres, beyond :data:`CLIP_END_M` on a miss); either may be None."""

    glb: str
    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    T_world_cam: list
    sun: dict | None
    world: float
    samples: int
    threads: int
    pixel_filter_px: float = 1.0
    our_light_model: bool = True
    repeats: int = 0
    colour_png: str | None = None
    depth_exr: str | None = None


@dataclass(frozen=True)
class CyclesTimes:
    """Seconds of a job: ``setup_s`` (factory reset, GLB import, scene set-up) and each render (``render_s``, the
    warm-up first), in Blender ``version``."""

    setup_s: float
    render_s: list
    version: str


def bpy_python() -> Path:
    """The interpreter that imports ``bpy``: ``$AEROSTEREO_BPY_PYTHON`` when set, else :data:`REPO_BPY_PYTHON`;
    :class:`BpyUnavailable` saying why there is none."""
    named = os.environ.get(BPY_PYTHON_ENV)
    python = Path(named) if named else REPO_BPY_PYTHON
    where = f"{BPY_PYTHON_ENV}={named}" if named else str(python)
    if not python.is_file():
        raise BpyUnavailable(f"{where}: not found (make it: {BPY_INSTALL})")
    problem = _bpy_import_problem(str(python))
    if problem:
        raise BpyUnavailable(f"{where} cannot import bpy: {problem}")
    return python


@functools.cache
def _bpy_import_problem(python: str) -> str:
    """The last line ``python -c "import bpy"`` printed when it failed, empty when it imports."""
    result = subprocess.run([python, "-c", "import bpy"], capture_output=True, text=True)
    lines = (result.stderr or result.stdout).strip().splitlines()
    return "" if result.returncode == 0 else (lines[-1] if lines else f"exit status {result.returncode}")


def run_cycles(job: CyclesJob) -> CyclesTimes:
    """Run ``job`` in Blender (:func:`bpy_python`'s interpreter, this file as the script); ``RuntimeError`` with the
    end of Blender's output when it fails."""
    python = bpy_python()
    with tempfile.TemporaryDirectory() as folder:
        job_json = Path(folder) / "job.json"
        job_json.write_text(json.dumps(asdict(job)))
        result = subprocess.run([str(python), __file__, str(job_json)], capture_output=True, text=True)
    if result.returncode != 0:
        raise RuntimeError(f"Blender failed (exit status {result.returncode}): {result.stderr.strip()[-2000:]}")
    return CyclesTimes(**json.loads(result.stdout.strip().splitlines()[-1]))


def frame_job(frame, view: int, glb: Path, samples: int, threads: int, **outputs) -> CyclesJob:
    """The job that renders rig camera ``view`` of a dataset frame (a :class:`sim.dataset.source.SourceFrame`) of the
    scene whose mesh is ``glb`` as the dataset has it: the frame's camera and pose, its sun at its recorded
    ``blender_strength`` (none under an overcast sky), the sky's light as the world, one sample at each pixel centre
    when the dataset has one per pixel (else a box over the pixel); ``outputs``: ``colour_png``, ``depth_exr``. Camera
    effects (``dataset.json`` ``sampling.effects``) are not reproduced. ``DatasetError`` for lens distortion,
    ``ValueError`` for an unlit frame (no light to give Blender) or a record without ``blender_strength``."""
    from sim.render.shade import Lighting

    frame.source.require_pinhole("rendering it in Blender")
    sun, camera = frame.record["sun"], frame.camera(view)
    if sun is None:
        raise ValueError(f"frame {frame.index} is unlit (the texture as captured): it has no sun or sky for Blender")
    if "blender_strength" not in sun:
        raise ValueError(f"frame {frame.index}: its sun has no blender_strength (rendered before it was recorded)")
    lamp = {key: sun[key] for key in ("azimuth_deg", "elevation_deg", "blender_strength")} if "azimuth_deg" in sun \
        else None
    spp = frame.source.description["sampling"]["samples_per_pixel"]
    return CyclesJob(
        glb=str(glb), **{key: camera[key] for key in ("fx", "fy", "cx", "cy", "width", "height")},
        T_world_cam=frame.T_world_cam(view).tolist(), sun=lamp,
        world=float(sun.get("ambient", Lighting().ambient)), samples=samples, threads=threads,
        pixel_filter_px=PIXEL_CENTRE_FILTER_PX if spp == 1 else 1.0, **outputs)


def read_depth(path: Path):
    """The depth EXR a job wrote: planar depth (H, W) float32 metres, +inf where nothing was hit."""
    import numpy as np
    import OpenEXR

    with OpenEXR.File(str(path)) as exr:
        (channel,) = exr.channels().values()
        depth = np.asarray(channel.pixels, dtype=np.float32)
    return np.where(depth >= CLIP_END_M, np.float32(np.inf), depth)


# Blender's side: run by the bpy interpreter, never imported by ours.

def _blender_scene(job: CyclesJob):
    """Blender's scene of ``job``: the GLB, the camera, the sun, the world, Cycles' settings."""
    import bpy
    from mathutils import Matrix

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=job.glb)
    scene = bpy.context.scene
    scene.camera = _blender_camera(scene, job, bpy, Matrix)
    if job.sun is not None:
        _add_sun(scene, job.sun, bpy)
    world = bpy.data.worlds.new("sky")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (job.world, job.world, job.world, 1.0)
    scene.world = world
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples, scene.cycles.use_denoising = job.samples, False  # as ours: the samples' plain mean
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", job.pixel_filter_px
    if job.our_light_model:
        _use_our_light_model(scene, bpy)
    scene.render.threads_mode, scene.render.threads = "FIXED", job.threads
    scene.render.use_persistent_data = True
    scene.render.resolution_x, scene.render.resolution_y = job.width, job.height
    scene.render.resolution_percentage = 100
    scene.render.dither_intensity = 0.0
    scene.view_settings.view_transform, scene.view_settings.look = "Standard", "None"
    scene.view_settings.exposure, scene.view_settings.gamma = 0.0, 1.0
    return scene


def _use_our_light_model(scene, bpy) -> None:
    """Direct light only (no bounce) on diffuse materials: what our renderer computes (sim/render/shade.py)."""
    scene.cycles.max_bounces = 0
    for material in bpy.data.materials:
        for node in material.node_tree.nodes if material.node_tree else ():
            if node.type == "BSDF_PRINCIPLED":
                node.inputs["Specular IOR Level"].default_value = 0.0


def _blender_camera(scene, job: CyclesJob, bpy, Matrix):
    """The job's pinhole camera at its pose: OpenCV axes (x right, y down, z forward) turned into Blender's (x right,
    y up, looking along -z); the principal point as a lens shift in units of the width (HORIZONTAL sensor fit)."""
    if abs(job.fx - job.fy) > 1e-6 * job.fx:
        raise ValueError(f"square pixels only: fx {job.fx} != fy {job.fy}")
    camera = bpy.data.cameras.new("camera")
    camera.sensor_fit, camera.sensor_width, camera.clip_end = "HORIZONTAL", 36.0, CLIP_END_M
    camera.lens = job.fx * camera.sensor_width / job.width
    camera.shift_x = ((job.width - 1) / 2 - job.cx) / job.width  # pixel centres at integers, as OpenCV's
    camera.shift_y = (job.cy - (job.height - 1) / 2) / job.width
    camera_object = bpy.data.objects.new("camera", camera)
    scene.collection.objects.link(camera_object)
    flip = Matrix.Diagonal((1.0, -1.0, -1.0, 1.0))
    camera_object.matrix_world = Matrix(job.T_world_cam) @ flip
    return camera_object


def _add_sun(scene, sun: dict, bpy) -> None:
    """A sun lamp shining from ``sun``'s azimuth and elevation (a lamp shines along its local -z: tilted by 90 - el
    about x, then turned by 180 - az about z) at its Blender Strength; a point-like disc, as our hard shadows."""
    lamp = bpy.data.lights.new("sun", "SUN")
    lamp.energy, lamp.angle = sun["blender_strength"], 0.0
    lamp_object = bpy.data.objects.new("sun", lamp)
    lamp_object.rotation_euler = (math.radians(90.0 - sun["elevation_deg"]), 0.0,
                                  math.radians(180.0 - sun["azimuth_deg"]))
    scene.collection.objects.link(lamp_object)


def _write_depth(scene, directory: str, bpy) -> None:
    """Have each render write its planar depth (``Depth``, float32 metres) as ``DIRECTORY/Depth.exr`` through the
    compositor (bpy 5.0.1 wrote a multilayer EXR of the render with its combined pass alone, the depth pass on)."""
    scene.view_layers[0].use_pass_z = True
    tree = bpy.data.node_groups.new("depth", "CompositorNodeTree")
    scene.compositing_node_group = tree
    layers, output = tree.nodes.new("CompositorNodeRLayers"), tree.nodes.new("CompositorNodeOutputFile")
    output.format.media_type, output.format.file_format = "IMAGE", "OPEN_EXR"
    output.format.color_mode, output.format.color_depth = "BW", "32"
    output.directory, output.file_name = directory, ""
    output.file_output_items.new("FLOAT", "Depth")
    tree.links.new(layers.outputs["Depth"], output.inputs["Depth"])


def _render_job(job: CyclesJob) -> CyclesTimes:
    """Set ``job`` up, render it ``1 + repeats`` times, write its files; the times."""
    import bpy

    start = time.perf_counter()
    scene = _blender_scene(job)
    with tempfile.TemporaryDirectory() as folder:
        if job.depth_exr:
            _write_depth(scene, folder, bpy)
        setup_s = time.perf_counter() - start
        render_s = []
        for _ in range(1 + job.repeats):
            start = time.perf_counter()
            bpy.ops.render.render()
            render_s.append(time.perf_counter() - start)
        if job.depth_exr:
            shutil.move(Path(folder) / "Depth.exr", job.depth_exr)
    if job.colour_png:
        settings = scene.render.image_settings
        settings.media_type, settings.file_format, settings.color_mode, settings.color_depth = "IMAGE", "PNG", "RGB", "8"
        bpy.data.images["Render Result"].save_render(job.colour_png, scene=scene)
    return CyclesTimes(setup_s, render_s, bpy.app.version_string)


if __name__ == "__main__":
    times = _render_job(CyclesJob(**json.loads(Path(sys.argv[1]).read_text())))
    print(json.dumps(asdict(times)))
