"""The whole recon run, stage by stage, resumable: photos + priors -> scene folder.

Each stage leaves a marker under ``SCENE_DIR/work``; a stage whose marker exists is not redone:

| stage | marker |
|---|---|
| sfm | ``work/sfm_report.json`` (model in ``work/sparse``, ENU metres) |
| undistort | ``work/dense/stereo/fusion.cfg`` |
| depth | ``work/dense/depth_report.json`` (per-image maps are also skipped when present) |
| fusion | ``work/fused.ply`` |
| mesh | ``work/mesh.ply`` (decimated: ``work/mesh_decimated.ply``) |
| texture | ``work/texture_report.json`` (textured mesh ``work/terrain.glb``; skipped with ``texture=False``) |
| scene | ``SCENE_DIR/scene.json`` (``terrain.glb`` or the ``terrain.ply`` fallback, and ``cameras.json``) |
"""

from __future__ import annotations

import json
import os
import shutil
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np
import pycolmap
import trimesh
from scipy.spatial import cKDTree
from tqdm import tqdm

from recon import dense, mesh as meshing, texture as texturing
from recon.atlas import AtlasOptions, texture_atlas
from recon.observed import observed_area
from recon.dense import DenseOptions
from flightplan.atomic import atomic_path, write_text_atomic
from recon.priors import (PosePriors, PriorsError, check_readable, focal_seed, list_photos, priors_from_exif,
                          read_geotags)
from recon.scene_out import scene_cameras, write_scene
from recon.sfm import MIN_PHOTOS, SfmOptions, camera_poses, run_sfm

STAGES = ("sfm", "undistort", "depth", "fusion", "mesh", "texture", "scene")
MESHES = ("3d", "2.5d", "poisson")
TEXTURES = ("atlas", "ortho", "none")

#: What the origin's ``h0_ellipsoid_m`` (and so every absolute height of the scene) really is, by priors source.
HEIGHT_DATUM = {
    "exif": "mean sea level: the first photo's EXIF GPS altitude, stored as h0_ellipsoid_m without a geoid "
            "correction (off from the ellipsoid by the local geoid undulation)",
    "geotags": "as geotags.json's origin (the drone's absolute take-off height; its origin_height_known says "
               "whether there was one)",
}


@dataclass(frozen=True)
class ReconOptions:
    """All knobs: SfM, dense, surface (``mesh``: "3d" Poisson cropped to the observed area grown by
    ``crop_margin`` x the median viewing distance and trimmed at ``poisson_trim``, "2.5d" height field, or "poisson"
    of the whole cloud), grid cell (None = 2 GSD), decimation, ``texture`` ("atlas": a texture atlas, each face from
    its best photo; "ortho": a true orthophoto, for 2.5-D fields; "none": vertex colours only), ``hold_out`` K (every K-th photo in name order is registered by SfM
    but left out of depth maps, fusion and texture; 0 = none)."""

    sfm: SfmOptions = field(default_factory=SfmOptions)
    dense: DenseOptions = field(default_factory=DenseOptions)
    mesh: str = "3d"
    grid_m: float | None = None
    poisson_depth: int = 10
    poisson_trim: float = 5.0
    crop_margin: float = 0.5
    decimate_error_m: float = 0.02
    texture: str = "atlas"
    texture_options: texturing.TextureOptions = field(default_factory=texturing.TextureOptions)
    atlas_options: AtlasOptions = field(default_factory=AtlasOptions)
    hold_out: int = 0

    def __post_init__(self) -> None:
        if self.mesh not in MESHES:
            raise ValueError(f"mesh must be one of {', '.join(MESHES)}, got {self.mesh!r}")
        if self.texture not in TEXTURES:
            raise ValueError(f"texture must be one of {', '.join(TEXTURES)}, got {self.texture!r}")
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
    """Photo names to use and their priors (geotags.csv, or EXIF GPS when no geotags are given).

    Photos that the geotags sidecar lists as ``untagged`` (capture could not place them) are left out; a photo
    that is not a readable image is a :class:`PriorsError` naming it.
    """
    names = list_photos(photo_dir)
    if len(names) < MIN_PHOTOS:
        raise PriorsError(f"{photo_dir}: need at least {MIN_PHOTOS} photos, found {len(names)}")
    if geotags_csv is None:
        return names, priors_from_exif(photo_dir, names)  # reads every photo's EXIF
    priors = read_geotags(geotags_csv)
    names = [n for n in names if n not in set(priors.untagged)]
    check_readable(photo_dir, names)
    return names, priors


def read_rgb(path: Path) -> np.ndarray:
    """An image file as (H, W, 3) uint8 RGB; a clear error naming the file if it cannot be read."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise PriorsError(f"{path}: cannot read this image")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def write_model_atomic(rec: pycolmap.Reconstruction, target: Path) -> None:
    """Write a COLMAP model folder under a temporary name, then rename it into place."""
    tmp = target.with_name(f".{target.name}.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    rec.write(tmp)
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
                 log=tqdm.write):
        self.photo_dir, self.geotags_csv = Path(photo_dir), geotags_csv and Path(geotags_csv)
        self.scene_dir, self.options, self.log = Path(scene_dir), options, log
        if self.scene_dir.exists() and not self.scene_dir.is_dir():
            raise ValueError(f"{self.scene_dir}: is a file; the output must be a (new or resumable) scene folder")
        self.work = self.scene_dir / "work"
        self.names, self.priors = load_priors(self.photo_dir, self.geotags_csv)
        if self.priors.untagged:
            self.log(f"[sfm] leaving out {len(self.priors.untagged)} photo(s) untagged by capture: "
                     f"{', '.join(self.priors.untagged[:10])}")
        self.seconds: dict[str, float] = {}
        k = self.options.hold_out
        self.held_out = frozenset(self.names[k - 1::k] if k else ())

    def run(self) -> dict:
        self.work.mkdir(parents=True, exist_ok=True)
        for stage in tqdm(STAGES, desc="recon", unit="stage"):
            t0 = time.perf_counter()
            done = getattr(self, f"stage_{stage}")()
            self.seconds[stage] = round(time.perf_counter() - t0, 2)
            self.log(f"[{stage}] {'already done' if done is False else 'done'} ({self.seconds[stage]} s)")
        return json.loads((self.scene_dir / "scene.json").read_text(encoding="utf-8"))

    # Each stage returns False when its marker says it was done already.

    def stage_sfm(self):
        report_path = self.work / "sfm_report.json"
        if report_path.exists():
            return False
        seed = focal_seed(self.photo_dir / self.names[0])
        rec, report = run_sfm(self.photo_dir, self.names, self.priors, seed, self.work / "sfm",
                              self.options.sfm, progress=lambda s: self.log(f"[sfm] {s}"))
        if report.unregistered:
            self.log(f"[sfm] WARNING: {len(report.unregistered)} photo(s) not registered: "
                     f"{', '.join(report.unregistered)}")
        for warning in report.warnings:
            self.log(f"[sfm] WARNING: {warning}")
        self.log(f"[sfm] {len(report.registered)}/{report.num_photos} registered, {report.num_points3d} points, "
                 f"reprojection {report.mean_reprojection_error_px:.2f} px, residual RMS vs priors "
                 f"{report.residual_rms_enu_m} m (E/N/U)")
        write_model_atomic(rec, self.work / "sparse")
        report.write(report_path)

    def stage_undistort(self):
        workspace = self.work / "dense"
        if (workspace / "stereo" / "fusion.cfg").exists():
            return False
        shutil.rmtree(workspace, ignore_errors=True)
        dense.undistort(self.work / "sparse", self.photo_dir, workspace, self.options.dense, self.held_out)

    def stage_depth(self):
        marker = self.work / "dense" / "depth_report.json"
        if marker.exists():
            return False
        coverage = dense.compute_depth_maps(self.work / "dense", self.options.dense,
                                            progress=lambda it: tqdm(it, desc="depth maps", unit="view"))
        write_text_atomic(marker, json.dumps({"valid_fraction": coverage}, indent=2))

    def stage_fusion(self):
        if (self.work / "fused.ply").exists():
            return False
        count = dense.fuse(self.work / "dense", self.work / "fused.ply", self.options.dense)
        self.log(f"[fusion] {count} points")

    def cell_size(self) -> float:
        """Two ground pixels of the depth maps (median depth / focal), metres."""
        rec = pycolmap.Reconstruction(self.work / "dense" / "sparse")
        focal = float(np.mean([cam.mean_focal_length() for cam in rec.cameras.values()]))
        return meshing.cell_size_from_gsd(median_view_depth(rec), focal)

    def observed_area(self) -> np.ndarray:
        """(K, 2) ENU polygon the registered cameras stand over (:func:`recon.observed.observed_area`)."""
        rec = pycolmap.Reconstruction(self.work / "dense" / "sparse")
        return observed_area(np.array([pose[:3, 3] for pose in camera_poses(rec).values()]))

    def stage_mesh(self):
        full, small = self.work / "mesh.ply", self.work / "mesh_decimated.ply"
        if full.exists() and (small.exists() or not self.options.decimate_error_m):
            return False
        if self.options.mesh == "3d":
            margin = self.options.crop_margin * median_view_depth(pycolmap.Reconstruction(self.work / "dense" / "sparse"))
            surface = meshing.surface_3d(self.work / "fused.ply", full, self.observed_area(), margin,
                                         self.options.poisson_depth, self.options.poisson_trim)
            self.log(f"[mesh] 3-D surface over the observed area + {margin:.1f} m, {len(surface.faces)} faces")
        elif self.options.mesh == "poisson":
            meshing.poisson_mesh(self.work / "fused.ply", full, self.options.poisson_depth)
        else:
            points, colors = meshing.read_point_cloud(self.work / "fused.ply")
            cell = self.options.grid_m or meshing.cell_size_for_density(points, self.cell_size())
            self.log(f"[mesh] height field, cell {cell:.3f} m, {len(points)} points")
            surface = meshing.height_field_mesh(meshing.height_field(points, colors, cell))
            with atomic_path(full) as tmp:
                surface.export(tmp)
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

    def stage_texture(self):
        marker = self.work / "texture_report.json"
        if marker.exists() or self.options.texture == "none":
            return False
        model = pycolmap.Reconstruction(self.work / "dense" / "sparse")
        photos = texturing.load_photos(model, self.work / "dense" / "images", read_rgb)
        surface = self.surface_mesh()
        progress = lambda it: tqdm(it, desc="texture", unit="photo")
        if self.options.texture == "atlas":
            textured = texture_atlas(surface, photos, self.options.atlas_options, progress,
                                     log=lambda message: self.log(f"[texture] {message}"))
            encoded, texel_m, coverage = textured.glb(), textured.texel_m, textured.coverage
        else:
            textured = texturing.orthophoto(surface, photos, self.options.texture_options, progress)
            encoded, texel_m, coverage = texturing.textured_glb(surface, textured), textured.texels.texel_m, \
                textured.coverage
        with atomic_path(self.work / "terrain.glb") as tmp:
            tmp.write_bytes(encoded)
        height, width = textured.image.shape[:2]
        self.log(f"[texture] {self.options.texture}: {width}x{height} texels of {texel_m:.3f} m, coverage "
                 f"{100 * coverage:.1f} %, exposure gains {min(textured.gains.values()):.3f}.."
                 f"{max(textured.gains.values()):.3f}")
        report = {"kind": self.options.texture, "texel_m": texel_m, "size_px": [width, height],
                  "coverage": coverage, "gains": textured.gains}
        write_text_atomic(marker, json.dumps(report, indent=2))

    def stage_scene(self):
        if (self.scene_dir / "scene.json").exists():
            return False
        surface = self.surface_mesh()
        sfm_report = json.loads((self.work / "sfm_report.json").read_text(encoding="utf-8"))
        provenance = {
            "generator": "recon.pipeline",
            "photos": str(self.photo_dir),
            "geotags": str(self.geotags_csv) if self.geotags_csv else "exif",
            "height_datum": HEIGHT_DATUM[self.priors.source],
            "options": asdict(self.options),
            "sfm": {k: sfm_report[k] for k in ("registered", "unregistered", "mean_reprojection_error_px",
                                                "residual_rms_enu_m", "tilt_correction_deg", "focal_final_px")},
        }
        textured = self.work / "terrain.glb"
        textured_now = self.options.texture != "none" and textured.exists()
        provenance["texture"] = (json.loads((self.work / "texture_report.json").read_text(encoding="utf-8"))
                                 if textured_now else "vertex colours (texturing switched off)")
        gains = provenance["texture"]["gains"] if textured_now else {}
        cameras = scene_cameras(pycolmap.Reconstruction(self.work / "sparse"), gains, self.held_out)
        mesh_name, encoded = ("terrain.glb", textured.read_bytes()) if textured_now else ("terrain.ply", None)
        write_scene(self.scene_dir, surface, self.priors.origin, provenance, mesh_name, encoded, cameras)
