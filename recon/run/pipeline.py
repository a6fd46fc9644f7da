"""The whole recon run, stage by stage, resumable: photos + priors -> scene folder.

Each stage records what made it in a stamp, ``work/stages/<stage>.json`` (see :mod:`recon.run.stages`): the options
it reads, its inputs and the fingerprint of the stage before it. A rerun skips the stages whose stamp is finished
with the same fingerprint, and redoes the first other one and every stage after it, saying why on stderr
(``[mesh] options changed (mesh: 2.5d -> poisson): redoing mesh, texture, scene, labels``):

| stage | options it reads (``ReconOptions``) | inputs | outputs |
|---|---|---|---|
| sfm | ``sfm.*`` but threads | photos (name, size, mtime), geotags files (SHA-256) | ``work/sfm_report.json``, model ``work/sparse`` (ENU m) |
| undistort | ``dense.max_image_size`` | | ``work/dense`` (images, ``sparse``, ``stereo/fusion.cfg``) |
| depth | ``dense`` pair choice, SGBM, consistency | | ``work/dense/depth_report.json``, per-image maps (below) |
| fusion | ``dense.fusion_*`` | | ``work/fused.ply`` |
| mesh | ``mesh``, ``grid_m``, ``poisson_depth``, ``poisson_trim``, ``crop_margin``, ``decimate_error_m``, ``water``, ``standing`` | | ``work/mesh.ply`` (``mesh_decimated.ply``), ``work/water.json`` (recon/surface/water.py) |
| texture | ``texture``, ``texture_options.*``, ``atlas_options.*`` | | ``work/texture_report.json``, ``work/terrain.glb``, ``work/texture_faces.npy`` (which faces a photo colours; none with ``texture="none"``), ``work/texture_sky_visibility.npz`` (the delight's sky bake, which the scene stage stores where it is its mesh's) |
| scene | ``texture`` | the sky visibility's bake settings, the face provenance's | ``SCENE_DIR/scene.json`` + ``terrain.glb`` (or ``terrain.ply``, vertex colours) + ``cameras.json`` + ``capture_light.png`` (delit) + ``sky_visibility.npz`` + ``face_provenance.npz`` (recon/surface/provenance.py) |
| labels | ``labels.*`` | | ``SCENE_DIR/labels.npz`` (per face: recon/semantics/labels.py), named in ``scene.json`` (rewritten) |

The exact table is :data:`recon.run.stages.STAGE_OPTIONS`. An interrupted depth stage keeps its finished per-image
maps when rerun with the same fingerprint; redone for another one, it deletes them first (:data:`STALE_OUTPUTS`).
Outputs of stages done before stamps existed (:data:`OLD_MARKERS`) are redone, with a message.
"""

from __future__ import annotations

import json
import os
import shutil
import time
from contextlib import nullcontext
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path

import cv2
import numpy as np
import pycolmap
import trimesh
from scipy.spatial import cKDTree

from capture.geotag_io import sidecar_path
from recon.appearance import texture as texturing
from recon.surface import dense, mesh as meshing, standing, water
from recon.appearance.atlas import AtlasOptions, texture_atlas
from recon.appearance.capture_sun import CaptureSuns, capture_suns, is_timed, utc_offset_text
from recon.surface.observed import viewed_area
from recon.surface.dense import DenseOptions
from recon.surface.provenance import GAP_CELLS, SurfaceEvidence
from recon.semantics.labels import LabelOptions, label_scene_dir
from cliutil.atomic import atomic_path, write_text_atomic
from cliutil.resources import require_disk
from cliutil.jsonfile import read_json
from recon.inputs.priors import (PosePriors, PriorsError, camera_seed, check_readable, list_photos, priors_from_exif,
                                 read_geotags, with_receiver_sigmas)
from cliutil.progress import StepProgress, counted, log_stderr
from recon.run.scene_out import CAPTURE_LIGHT_FILE, scene_cameras, write_scene
from recon.appearance.shadow_timing import (fit_utc_offset, refine_capture_time, shadow_views, start_fit,
                                            untextured_scene)
from recon.sfm.cameras import camera_poses
from recon.sfm.options import SfmOptions
from recon.sfm.pipeline import MIN_PHOTOS, check_inputs, run_sfm, sfm_disk_bytes
from recon.run.stages import STAGES, StageStamps, file_sha256, photo_inputs, stage_records
from sim.render.capture_light import write_capture_light
from sim.render.glb import GEOREF_FORMAT
from sim.render.labels import LABELS_FILE
from sim.render.provenance import FAR_M, FORMAT as PROVENANCE_FORMAT
from sim.render.sky import bake_settings
from sim.render.sky_file import SkyVisibility, write_sky_visibility

MESHES = ("3d", "2.5d", "poisson")
TEXTURES = ("atlas", "ortho", "none")
WATER = ("plane", "none")
STANDING = ("heightfield", "none")

#: What each stage wrote before stages were stamped (relative to the scene folder): such a stage is redone.
OLD_MARKERS = {"sfm": "work/sfm_report.json", "undistort": "work/dense/stereo/fusion.cfg",
               "depth": "work/dense/depth_report.json", "fusion": "work/fused.ply", "mesh": "work/mesh.ply",
               "texture": "work/texture_report.json", "scene": "scene.json", "labels": LABELS_FILE}

#: Which faces of the surface mesh a photo colours (texture stage, read by the scene stage's face provenance).
TEXTURE_FACES = "texture_faces.npy"
#: The sky visibility the texture stage baked to take the capture light out (sim/render/sky_file.py), kept for the
#: scene stage, which stores it rather than bake the same mesh again (recon/run/scene_out.py: store_sky_visibility).
TEXTURE_SKY_FILE = "texture_sky_visibility.npz"

#: Partial outputs (relative to ``work``) that a stage reuses when it resumes its own interrupted run, and that are
#: deleted before it is redone for another fingerprint.
STALE_OUTPUTS = {"depth": ("dense/stereo/depth_maps", "dense/stereo/normal_maps")}

#: What the origin's ``h0_ellipsoid_m`` (and so every absolute height of the scene) really is, by priors source.
HEIGHT_DATUM = {
    "exif": "the receiver's: the first photo's GPS altitude (DJI XMP AbsoluteAltitude, else EXIF; mean sea level "
            "for a consumer GPS), stored as h0_ellipsoid_m without a geoid correction (off from the ellipsoid by "
            "the local geoid undulation where it is MSL)",
    "geotags": "as geotags.json's origin (the drone's absolute take-off height; its origin_height_known says "
               "whether there was one)",
}


@dataclass(frozen=True)
class ReconOptions:
    """All knobs: SfM, dense, surface (``mesh``: "3d" Poisson cropped to the observed area grown by
    ``crop_margin`` x the median viewing distance and trimmed at ``poisson_trim``, "2.5d" height field, or "poisson"
    of the whole cloud), grid cell (None = 2 GSD), decimation, ``water`` ("plane": open water the fused points show
    becomes a plane at its level, recon/surface/water.py; "none": the raw surface), ``standing`` ("heightfield": the
    standing objects the 3-D surface smoothed away put back from the fused points' height field,
    recon/surface/standing.py; "none": not), ``texture`` ("atlas": a texture atlas, each face from
    its best photo; "ortho": a true orthophoto, for 2.5-D fields; "none": vertex colours only), ``hold_out`` K (every K-th photo in name order is registered by SfM
    but left out of depth maps, fusion and texture; 0 = none), ``delight``: an atlas of photos with a UTC time stores
    the albedo and the capture light it divided out (recon/appearance/delight.py), so the twin can be lit by another
    sun; ``capture_sun``: (azimuth, elevation) degrees of the sun of every photo when it is known better than their
    times say (a virtual flight lit by a fixed sun), None: from each photo's UTC time; ``capture_sun_sky_ratio``: the
    capture light's sun/sky irradiance ratio per channel where it was measured, None: fitted from the texture's
    shadow edges; ``capture_utc_offset_h``: the
    zone of the photos' EXIF clocks (hours east of UTC) where they did not write it, None: found from their shadows;
    ``labels``: the thresholds the faces are labelled with (recon/semantics/labels.py)."""

    sfm: SfmOptions = field(default_factory=SfmOptions)
    dense: DenseOptions = field(default_factory=DenseOptions)
    mesh: str = "3d"
    grid_m: float | None = None
    poisson_depth: int = 10
    poisson_trim: float = 5.0
    crop_margin: float = 0.5
    decimate_error_m: float = 0.02
    water: str = "plane"
    standing: str = "none"
    texture: str = "atlas"
    texture_options: texturing.TextureOptions = field(default_factory=texturing.TextureOptions)
    atlas_options: AtlasOptions = field(default_factory=AtlasOptions)
    hold_out: int = 0
    delight: bool = True
    capture_sun: tuple[float, float] | None = None
    capture_sun_sky_ratio: tuple[float, float, float] | None = None
    capture_utc_offset_h: float | None = None
    labels: LabelOptions = field(default_factory=LabelOptions)

    def __post_init__(self) -> None:
        for name, choices in (("mesh", MESHES), ("water", WATER), ("standing", STANDING), ("texture", TEXTURES)):
            if getattr(self, name) not in choices:
                raise ValueError(f"{name} must be one of {', '.join(choices)}, got {getattr(self, name)!r}")
        if self.capture_sun is not None and not (-360 <= self.capture_sun[0] <= 360 and
                                                 0 < self.capture_sun[1] <= 90):
            raise ValueError(f"capture sun must be an azimuth in [-360, 360] and an elevation in (0, 90] degrees, "
                             f"got {self.capture_sun}")
        if self.capture_sun_sky_ratio is not None and not (len(self.capture_sun_sky_ratio) == 3 and
                                                           all(0 < r < 1000 for r in self.capture_sun_sky_ratio)):
            raise ValueError(f"capture sun/sky ratio must be three values above 0 and below 1000, "
                             f"got {self.capture_sun_sky_ratio}")
        if self.capture_sun_sky_ratio is not None and not (self.delight and self.texture == "atlas"):
            keeps = "--keep-capture-light" if not self.delight else f"--texture {self.texture}"
            raise ValueError(f"a capture sun/sky ratio is divided out of an atlas only, not with {keeps}")
        if self.capture_utc_offset_h is not None and not -14.0 <= self.capture_utc_offset_h <= 14.0:
            raise ValueError(f"capture UTC offset must be in [-14, +14] hours, got {self.capture_utc_offset_h}")
        if not (np.isfinite(self.crop_margin) and self.crop_margin >= 0):
            raise ValueError(f"crop margin must be a non-negative multiple of the viewing distance, got {self.crop_margin}")
        if self.hold_out == 1 or self.hold_out < 0:
            raise ValueError(f"hold-out must be 0 (off) or K >= 2 (every K-th photo), got {self.hold_out}")
        if self.grid_m is not None and not (np.isfinite(self.grid_m) and self.grid_m > 0):
            raise ValueError(f"grid cell must be a positive number of metres, got {self.grid_m}")
        if not (np.isfinite(self.decimate_error_m) and self.decimate_error_m >= 0):
            raise ValueError(f"decimation error must be 0 (off) or a positive number of metres, "
                             f"got {self.decimate_error_m}")


def load_priors(photo_dir: Path, geotags_csv: Path | None) -> tuple[list[str], PosePriors]:
    """Photo names to use and their priors (geotags.csv, or the photos' own GPS when no geotags are given), each
    photo's sigma from its own receiver (RTK fixed in its XMP, else consumer GPS).

    Photos that the geotags sidecar lists as ``untagged`` (capture could not place them) are left out; a photo
    that is not a readable image, or whose image data is cut short (a truncated JPEG), is a :class:`PriorsError`
    naming it (:func:`recon.inputs.priors.check_readable`), and so are too few photos left and photos without a geotag
    (:func:`recon.sfm.pipeline.check_inputs`): all before any stage starts.
    """
    names = list_photos(photo_dir)
    if len(names) < MIN_PHOTOS:
        raise PriorsError(f"{photo_dir}: need at least {MIN_PHOTOS} photos, found {len(names)}")
    if geotags_csv is None:
        priors = priors_from_exif(photo_dir, names)  # reads every photo's EXIF and XMP
    else:
        geotags = read_geotags(geotags_csv)
        names = [n for n in names if n not in set(geotags.untagged)]
        if len(names) < MIN_PHOTOS:
            raise PriorsError(f"{geotags_csv}: {len(geotags.untagged)} of the photos in {photo_dir} are untagged "
                              f"(geotags.json), leaving {len(names)}; need at least {MIN_PHOTOS}")
        priors = with_receiver_sigmas(geotags, photo_dir)
    check_inputs(names, priors)
    check_readable(photo_dir, names)
    return names, priors


def read_rgb(path: Path) -> np.ndarray:
    """An image file as (H, W, 3) uint8 RGB; a clear error naming the file if it cannot be read."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise PriorsError(f"{path}: cannot read this image")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def write_model_atomic(rec: pycolmap.Reconstruction, target: Path) -> None:
    """Write a COLMAP model folder under a temporary name, check that it reads back whole (``OSError`` naming
    ``target`` otherwise, e.g. on a full disk; the temporary is deleted), then rename it into place."""
    tmp = target.with_name(f".{target.name}.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        tmp.mkdir(parents=True)
        rec.write(tmp)
        dense.check_model_written(tmp, rec, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    shutil.rmtree(target, ignore_errors=True)
    os.replace(tmp, target)


def median_view_depth(rec: pycolmap.Reconstruction) -> float:
    """Median planar depth (model units) of the sparse points over all registered views."""
    depths = []
    for image in rec.images.values():
        if not image.has_pose:
            continue
        pose = image.cam_from_world().matrix()
        xyz = np.array([rec.points3D[p.point3D_id].xyz for p in image.points2D if p.has_point3D()])
        if len(xyz):
            depths.append(np.median(xyz @ pose[:, :3].T[:, 2] + pose[2, 3]))
    return float(np.median(depths))


class Recon:
    """One run into ``scene_dir``; ``run()`` executes the stages not yet done and returns a summary dict."""

    def __init__(self, photo_dir: Path, geotags_csv: Path | None, scene_dir: Path, options: ReconOptions,
                 log=log_stderr, progress=None, loaded: tuple[list[str], PosePriors] | None = None):
        """``log``: one line at a time (default stderr); ``progress``: ``(stage, step, done, total)`` counts from
        inside a stage (default: :class:`cliutil.progress.StepProgress` bars or lines on stderr); ``loaded``: what
        :func:`load_priors` returned for these photos and geotags, where the caller checked them already."""
        self.photo_dir, self.geotags_csv = Path(photo_dir), geotags_csv and Path(geotags_csv)
        self.scene_dir, self.options, self.log = Path(scene_dir), options, log
        self.progress = progress
        if self.scene_dir.exists() and not self.scene_dir.is_dir():
            raise ValueError(f"{self.scene_dir}: is a file; the output must be a (new or resumable) scene folder")
        self.work = self.scene_dir / "work"
        self.names, self.priors = loaded or load_priors(self.photo_dir, self.geotags_csv)
        if options.mesh == "2.5d" and options.grid_m is not None:  # refuse before SfM what meshing could not hold
            extent = np.ptp(self.priors.positions_enu[:, :2], axis=0)  # orbits and grids surround what they see
            meshing.require_height_field_memory(*extent, options.grid_m, "at least the photos' extent")
        self.seconds: dict[str, float] = {}
        k = self.options.hold_out
        self.held_out = frozenset(self.names[k - 1::k] if k else ())

    def inputs(self) -> dict[str, dict]:
        """The files each stage reads beyond the stages before it, for its fingerprint (sfm: photos and geotags;
        texture: the glTF convention it writes, so a terrain.glb written before the +Y-up GLBs is redone, not
        taken for one, and the file saying which faces a photo colours, so a texture stage that wrote none is redone;
        scene: the settings its sky visibility is baked with and its faces' provenance is found with, so a scene
        made with others, or before scenes stored them, is redone)."""
        geotags = "exif" if self.geotags_csv is None else {
            path.name: file_sha256(path) for path in (self.geotags_csv, sidecar_path(self.geotags_csv))}
        return {"sfm": {"photos": photo_inputs(self.photo_dir, self.names), "geotags": geotags},
                "texture": {"glb": GEOREF_FORMAT, "faces": TEXTURE_FACES},
                "scene": {"sky_visibility": bake_settings(),
                          "face_provenance": {"format": PROVENANCE_FORMAT, "gap_cells": GAP_CELLS, "far_m": FAR_M}}}

    def stage_plan(self):
        """Each stage's record, the stamps and the plan (the stages to do, and why) they make together."""
        records = stage_records(self.options, self.inputs())
        stamps = StageStamps(self.work / "stages")
        return records, stamps, stamps.plan(records, lambda stage: (self.scene_dir / OLD_MARKERS[stage]).exists())

    def check_before_run(self) -> None:
        """The check :meth:`run` makes before its first stage that writes nothing (room on the disk for SfM, where
        SfM is still to do), for a caller that checks several runs before it starts any (``recon area``)."""
        if "sfm" in self.stage_plan()[2].todo:
            self.check_room_for_sfm()

    def run(self) -> dict:
        """Run the stages the stamps do not show as done (see the module docstring); the scene.json dict.
        ``self.seconds``: wall time per stage in this run (0 for a stage already done)."""
        records, stamps, plan = self.stage_plan()
        created = not self.scene_dir.exists()
        self.work.mkdir(parents=True, exist_ok=True)  # a read-only disk says so here, before any size check
        try:
            if "sfm" in plan.todo:
                self.check_room_for_sfm()
            self.run_stages(plan, records, stamps)
        except BaseException:
            if created and not any(stage in self.seconds for stage in plan.todo):
                shutil.rmtree(self.scene_dir, ignore_errors=True)  # no stage finished: nothing worth resuming
            raise
        return read_json(self.scene_dir / "scene.json")

    def run_stages(self, plan, records: dict, stamps: StageStamps) -> None:
        """Say what is done already and run the stages of ``plan.todo``, stamping each (and timing it in
        ``self.seconds``) as it starts and finishes."""
        if self.priors.untagged:  # said once the checks have passed, so a refusal stays one line
            self.log(f"[sfm] leaving out {len(self.priors.untagged)} photo(s) untagged by capture: "
                     f"{', '.join(self.priors.untagged[:10])}")
        for stage in STAGES[:len(STAGES) - len(plan.todo)]:
            self.seconds[stage] = 0.0
            self.log(f"[{stage}] already done")
        if plan.reason:
            self.log(f"[{plan.todo[0]}] {plan.reason}: redoing {', '.join(plan.todo)}")
        for stage in plan.todo:
            if not (plan.resume and stage == plan.todo[0]):
                for stale in STALE_OUTPUTS.get(stage, ()):
                    shutil.rmtree(self.work / stale, ignore_errors=True)
            self.log(f"[{stage}] running (stage {STAGES.index(stage) + 1}/{len(STAGES)})")
            stamps.write(stage, *records[stage], finished=False)
            t0 = time.perf_counter()
            getattr(self, f"stage_{stage}")()
            stamps.write(stage, *records[stage], finished=True)
            self.seconds[stage] = round(time.perf_counter() - t0, 2)
            self.log(f"[{stage}] done ({self.seconds[stage]} s)")

    def step_progress(self, stage: str):
        """The progress callback ``(step, done, total)`` for counts from inside ``stage``."""
        if self.progress is None:
            return StepProgress(stage, self.log)
        return nullcontext(partial(self.progress, stage))

    def check_room_for_sfm(self):
        """:class:`~cliutil.errors.BadInput` when the disk of the scene folder has less free space than
        SfM may need (:func:`recon.sfm.pipeline.sfm_disk_bytes`): COLMAP would abort the process when its database
        cannot grow."""
        features = self.options.sfm.max_num_features
        require_disk(self.work, sfm_disk_bytes(len(self.names), features),
                     f"SfM of {len(self.names)} photos at up to {features} features each (--max-features)")

    def stage_sfm(self):
        seed = camera_seed(self.photo_dir / self.names[0])
        with self.step_progress("sfm") as progress:
            rec, report = run_sfm(self.photo_dir, self.names, self.priors, seed, self.work / "sfm",
                                  self.options.sfm, log=lambda s: self.log(f"[sfm] {s}"), progress=progress)
        if report.unregistered:
            self.log(f"[sfm] WARNING: {len(report.unregistered)} photo(s) not registered: "
                     f"{', '.join(report.unregistered)}")
        for warning in report.warnings:
            self.log(f"[sfm] WARNING: {warning}")
        self.log(f"[sfm] {len(report.registered)}/{report.num_photos} registered, {report.num_points3d} points, "
                 f"reprojection {report.mean_reprojection_error_px:.2f} px, residual RMS vs priors "
                 f"{report.residual_rms_enu_m} m (E/N/U)")
        offset = report.georegistration["tag_offset"]
        if offset["applied"]:
            self.log(f"[sfm] the tags lead the cameras by {offset['along_track_offset_m']:+.3f} m along the track "
                     f"(+-{offset['along_track_sigma_m']:.3f}): residual RMS with it removed "
                     f"{report.residual_rms_enu_m_offset_removed} m (E/N/U)")
        write_model_atomic(rec, self.work / "sparse")
        report.write(self.work / "sfm_report.json")

    def stage_undistort(self):
        workspace = self.work / "dense"
        shutil.rmtree(workspace, ignore_errors=True)
        dense.undistort(self.work / "sparse", self.photo_dir, workspace, self.options.dense, self.held_out)

    def stage_depth(self):
        marker = self.work / "dense" / "depth_report.json"
        with self.step_progress("depth") as progress:
            coverage = dense.compute_depth_maps(self.work / "dense", self.options.dense,
                                                progress=lambda views: counted(views, "depth maps", progress))
        write_text_atomic(marker, json.dumps({"valid_fraction": coverage}, indent=2))

    def stage_fusion(self):
        count = dense.fuse(self.work / "dense", self.work / "fused.ply", self.options.dense)
        self.log(f"[fusion] {count} points")

    def cell_size(self) -> float:
        """Two ground pixels of the depth maps (median depth / focal), metres."""
        rec = pycolmap.Reconstruction(self.work / "dense" / "sparse")
        focal = float(np.mean([cam.mean_focal_length() for cam in rec.cameras.values()]))
        return meshing.cell_size_from_gsd(median_view_depth(rec), focal)

    def height_field_cell(self, points: np.ndarray) -> float:
        """The 2.5-D height field's cell (metres): ``grid_m``, else two ground pixels grown until the fused
        ``points`` (N, 3) fill the occupied cells (:func:`recon.surface.mesh.cell_size_for_density`)."""
        return self.options.grid_m or meshing.cell_size_for_density(points, self.cell_size())

    def surface_evidence(self, surface: trimesh.Trimesh, textured: bool) -> SurfaceEvidence:
        """What the reconstruction measured, for the scene's face provenance (:mod:`recon.surface.provenance`): the
        fused points, the gap of :data:`~recon.surface.provenance.GAP_CELLS` surface cells (the height field's, else
        two ground pixels of the depth maps) and, where a texture was made, which faces of ``surface`` a photo
        colours."""
        points, _ = meshing.read_point_cloud(self.work / "fused.ply")
        cell = self.height_field_cell(points) if self.options.mesh == "2.5d" else self.cell_size()
        face_seen = np.load(self.work / TEXTURE_FACES) if textured else None
        return SurfaceEvidence(points, GAP_CELLS * cell, face_seen, tuple(water.read_water(self.work / water.WATER_FILE)))

    @staticmethod
    def observed_area(rec: pycolmap.Reconstruction) -> np.ndarray:
        """(K, 2) ENU polygon the registered cameras of ``rec`` stand over and look at
        (:func:`recon.surface.observed.viewed_area`, the ground at the sparse points' median height)."""
        ground_z = float(np.median([point.xyz[2] for point in rec.points3D.values()]))
        return viewed_area(np.array(list(camera_poses(rec).values())), ground_z)

    def stage_mesh(self):
        full, small = self.work / "mesh.ply", self.work / "mesh_decimated.ply"
        if self.options.mesh == "3d":
            rec = pycolmap.Reconstruction(self.work / "dense" / "sparse")
            margin = self.options.crop_margin * median_view_depth(rec)
            surface = meshing.surface_3d(self.work / "fused.ply", full, self.observed_area(rec), margin,
                                         self.cell_size(), self.options.poisson_depth, self.options.poisson_trim)
            self.log(f"[mesh] 3-D surface over the observed area + {margin:.1f} m, {len(surface.faces)} faces")
            if self.options.standing == "heightfield":
                points, colors = meshing.read_point_cloud(self.work / "fused.ply")
                cell = self.height_field_cell(points)
                cells = standing.put_back(surface, full, points, colors, cell)
                self.log(f"[mesh] standing objects put back from the height field: {cells} cells of {cell:.3f} m")
        elif self.options.mesh == "poisson":
            meshing.poisson_mesh(self.work / "fused.ply", full, self.options.poisson_depth)
        else:
            points, colors = meshing.read_point_cloud(self.work / "fused.ply")
            cell = self.height_field_cell(points)
            self.log(f"[mesh] height field, cell {cell:.3f} m, {len(points)} points")
            surface = meshing.height_field_mesh(meshing.height_field(points, colors, cell))
            with atomic_path(full) as tmp:
                surface.export(tmp)
        bodies = []
        if self.options.water == "plane":
            bodies = water.flatten_water(full, self.work / "fused.ply")
            self.log(f"[mesh] water: {water.describe(bodies)}")
        water.write_water(self.work / water.WATER_FILE, bodies)
        if self.options.decimate_error_m:
            meshing.decimate(full, small, self.options.decimate_error_m)

    def surface_mesh(self) -> trimesh.Trimesh:
        """The final (decimated if asked) surface mesh, ENU metres, with vertex colours (decimation drops them:
        each kept vertex takes the colour of the nearest vertex of the full mesh)."""
        full = trimesh.load(self.work / "mesh.ply", process=False)
        if not self.options.decimate_error_m:
            return full
        small = trimesh.load(self.work / "mesh_decimated.ply", process=False)
        if small.visual.kind != "vertex" and full.visual.kind == "vertex":
            nearest = cKDTree(full.vertices).query(small.vertices)[1]
            small.visual.vertex_colors = np.asarray(full.visual.vertex_colors)[nearest]
        return small

    def held_out_photos(self) -> list:
        """The registered held-out photos, undistorted like the dense views into ``work/held_out`` (for their
        exposure gains only: they colour nothing)."""
        sparse = pycolmap.Reconstruction(self.work / "sparse")
        held = {image.name for image in sparse.images.values() if image.has_pose and image.name in self.held_out}
        if not held:
            return []
        workspace = self.work / "held_out"
        shutil.rmtree(workspace, ignore_errors=True)
        others = {image.name for image in sparse.images.values()} - held
        dense.undistort(self.work / "sparse", self.photo_dir, workspace, self.options.dense, others)
        return texturing.load_photos(pycolmap.Reconstruction(workspace / "sparse"), workspace / "images", read_rgb)

    def stage_texture(self):
        marker = self.work / "texture_report.json"
        if self.options.texture == "none":
            return
        model = pycolmap.Reconstruction(self.work / "dense" / "sparse")
        photos = texturing.load_photos(model, self.work / "dense" / "images", read_rgb)
        surface = self.surface_mesh()
        with self.step_progress("texture") as progress:
            count = lambda items: counted(items, "photos", progress)
            if self.options.texture == "atlas":
                suns, kept = self.capture_suns(photos, surface)
                textured = texture_atlas(surface, photos, self.options.atlas_options, count,
                                         log=lambda message: self.log(f"[texture] {message}"),
                                         held_out=self.held_out_photos(),
                                         sun_enu=None if suns is None else
                                         suns.for_names([photo.name for photo in photos]).directions_enu,
                                         sun_sky_ratio=self.options.capture_sun_sky_ratio)
                encoded, texel_m, coverage = textured.glb(self.priors.origin), textured.texel_m, textured.coverage
                face_seen, sky_bake = textured.face_seen, textured.sky
            else:
                suns, kept = None, "an orthophoto keeps the capture day's light (--texture atlas takes it out)"
                textured = texturing.orthophoto(surface, photos, self.options.texture_options, count)
                encoded, texel_m, coverage = texturing.textured_glb(surface, textured, self.priors.origin), textured.texels.texel_m, \
                    textured.coverage
                face_seen, sky_bake = textured.face_seen(surface), None
        if kept:
            self.log(f"[texture] capture light kept: {kept}")
        with atomic_path(self.work / "terrain.glb") as tmp:
            tmp.write_bytes(encoded)
        with atomic_path(self.work / TEXTURE_FACES) as tmp:
            with open(tmp, "wb") as stream:
                np.save(stream, face_seen)
        self.keep_sky_bake(sky_bake)
        height, width = textured.image.shape[:2]
        self.log(f"[texture] {self.options.texture}: {width}x{height} texels of {texel_m:.3f} m, coverage "
                 f"{100 * coverage:.1f} %, exposure gains {min(textured.gains.values()):.3f}.."
                 f"{max(textured.gains.values()):.3f}")
        report = {"kind": self.options.texture, "texel_m": texel_m, "size_px": [width, height],
                  "coverage": coverage, "gains": textured.gains,
                  "capture_light": self.write_capture_light(textured, suns, kept)}
        write_text_atomic(marker, json.dumps(report, indent=2))

    def keep_sky_bake(self, bake: tuple[SkyVisibility, dict] | None) -> None:
        """Store the texture's sky ``bake`` (visibility, what it was baked from) for the scene stage, or remove one of
        an earlier run where there is none."""
        if bake is None:
            (self.work / TEXTURE_SKY_FILE).unlink(missing_ok=True)
        else:
            write_sky_visibility(self.work / TEXTURE_SKY_FILE, *bake)

    def capture_suns(self, photos, surface: trimesh.Trimesh) -> tuple[CaptureSuns | None, str]:
        """The capture sun of every photo (of ``photos`` where given as one sun; of every prior photo where timed),
        timed (or its clock and yaw refined) by the shadows ``surface`` casts in ``photos``
        (:mod:`recon.appearance.shadow_timing`); or None and why the light is kept (delighting is off, the photos cannot
        be timed, or the sun was down at their times)."""
        names = [photo.name for photo in photos]
        if not self.options.delight:
            return None, "--keep-capture-light"
        if self.options.capture_sun is not None:
            azimuth, elevation = self.options.capture_sun
            return CaptureSuns(tuple(names), np.full(len(names), azimuth), np.full(len(names), elevation),
                               "given (--capture-sun)"), ""
        times, source, utc_offset_h = self.photo_times()
        if times is None:
            return None, ("the photos have no time (EXIF DateTimeOriginal) to find the capture sun from; give "
                          "--capture-sun AZ,EL to relight")
        twin, origin = untextured_scene(surface.vertices, surface.faces), self.priors.origin
        views = shadow_views(twin, photos, dict(zip(self.priors.names, times)))
        if utc_offset_h is not None:
            timing = refine_capture_time(twin, views, origin, start_fit(twin, views, origin, utc_offset_h))
        elif (timing := fit_utc_offset(twin, views, origin)) is None:
            return None, ("the photos' EXIF clocks carry no time zone and no UTC offset explains their shadows on the "
                          "twin clearly; give --capture-utc-offset +HH:MM or --capture-sun AZ,EL to relight")
        else:
            source = f"{source}, UTC offset {timing.utc_offset_h:+.2f} h found from the shadows"
        self.log(f"[texture] capture time from {source}: clock {timing.clock_correction_min:+.0f} min, yaw "
                 f"{timing.yaw_deg:+.0f} deg, shadow edge contrast {timing.before:.2f} -> {timing.contrast:.2f} "
                 f"(log), shadow IoU {timing.iou:.2f}")
        suns = capture_suns(self.priors.names, times - 3600.0 * timing.utc_offset_h, origin, source, timing)
        if np.all(suns.elevation_deg <= 0):
            return None, ("the sun was below the horizon at every photo's UTC time (give --capture-sun AZ,EL if the "
                          "times are not the photos' own)")
        return suns, ""

    def photo_times(self) -> tuple[np.ndarray | None, str, float | None]:
        """Each prior photo's time (seconds since the epoch, its clock's), where it came from, and the clock's UTC
        offset (hours; 0 for UTC) where known, else None (an EXIF clock in an unknown zone); no times where some
        photo has none."""
        priors, offset_h = self.priors, self.options.capture_utc_offset_h
        if is_timed(priors.utc_time_s):
            return priors.utc_time_s, priors.source, 0.0
        if not is_timed(priors.clock_time_s):
            return None, "", None
        if offset_h is not None:
            return priors.clock_time_s, f"EXIF clock at UTC{utc_offset_text(offset_h)}", offset_h
        return priors.clock_time_s, "EXIF clock", None

    def write_capture_light(self, textured, suns: CaptureSuns | None, kept: str) -> dict:
        """Write ``work/capture_light.png`` when the atlas divided its light out; what the texture report says
        (``kept``: why the light stayed, when no capture sun was known)."""
        path = self.work / CAPTURE_LIGHT_FILE
        path.unlink(missing_ok=True)
        if suns is None:
            return {"applied": False, "reason": kept}
        report = {"applied": textured.capture_light is not None, "capture_sun": suns.description(),
                  "sun_sky_ratio": np.round(textured.delighting.ratio, 4).tolist(),
                  "sun_sky_ratio_from": "fitted" if self.options.capture_sun_sky_ratio is None else "measured",
                  "shadow_edge_blocks": textured.delighting.blocks, "relit_texels": textured.delighting.relit}
        if textured.capture_light is None:
            report["reason"] = "no shadow edge to fit a sun on (an overcast capture keeps its colours)"
        else:
            write_capture_light(path, textured.capture_light)
        return report

    def stage_scene(self):
        surface = self.surface_mesh()
        sfm_report = json.loads((self.work / "sfm_report.json").read_text(encoding="utf-8"))
        provenance = {
            "generator": "recon.pipeline",
            "photos": str(self.photo_dir),
            "geotags": str(self.geotags_csv) if self.geotags_csv else "exif",
            "height_datum": HEIGHT_DATUM[self.priors.source],
            "options": asdict(self.options),
            "sfm": {k: sfm_report.get(k) for k in ("registered", "unregistered", "mean_reprojection_error_px",
                                                    "residual_rms_enu_m", "prior_sigma_enu_m", "prior_tilt_sigma_deg",
                                                    "tilt_correction_deg", "focal_final_px")},
        }
        textured = self.work / "terrain.glb"
        textured_now = self.options.texture != "none" and textured.exists()
        provenance["texture"] = (json.loads((self.work / "texture_report.json").read_text(encoding="utf-8"))
                                 if textured_now else "vertex colours (texturing switched off)")
        gains = provenance["texture"]["gains"] if textured_now else {}
        suns = provenance["texture"].get("capture_light", {}).get("capture_sun", {}).get("per_photo", {}) \
            if textured_now else {}
        cameras = scene_cameras(pycolmap.Reconstruction(self.work / "sparse"), gains, self.held_out, suns)
        mesh_name, encoded = ("terrain.glb", textured.read_bytes()) if textured_now else ("terrain.ply", None)
        light = self.work / CAPTURE_LIGHT_FILE
        capture_light = (light.read_bytes(), provenance["texture"]["capture_light"]) if textured_now and \
            light.is_file() else None
        scene_json = write_scene(self.scene_dir, surface, self.priors.origin, provenance, mesh_name, encoded, cameras,
                                 capture_light, self.surface_evidence(surface, textured_now),
                                 self.work / TEXTURE_SKY_FILE if textured_now else None)
        shares = read_json(scene_json)["face_provenance"]["shares"]
        self.log("[scene] face provenance, share of faces: " + ", ".join(
            f"{name} {100 * share['faces']:.1f} %" for name, share in shares.items()))

    def stage_labels(self):
        label_scene_dir(self.scene_dir, self.options.labels, self.log)

