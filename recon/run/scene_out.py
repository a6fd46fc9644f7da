"""Write the scene folder of INTERFACES.md: a mesh in local ENU metres, ``cameras.json``, the mesh's baked sky
visibility (``sky_visibility.npz``, sim/render/sky_file.py), which of its faces were measured
(``face_provenance.npz``, recon/surface/provenance.py) and ``scene.json``.

The normal case is a textured GLB from ``recon/appearance/texture.py`` (``encoded`` bytes); the fallback is the mesh
with vertex colours exported by trimesh (PLY). ``cameras.json`` (sim/render/scene_cameras.py) holds the registered
photos of the final SfM model with their exposure gains; ``scene.json``'s ``observed_area_m`` is the ground polygon (ENU
x, y metres) they stand over and look at (:func:`recon.surface.observed.viewed_area`), where the twin is expected to
hold.
"""

from __future__ import annotations

import json
from pathlib import Path

from collections.abc import Collection, Mapping, Sequence

import numpy as np
import pycolmap
import trimesh

from flightplan.geodesy import LocalFrame
from cliutil.atomic import atomic_path, write_text_atomic
from recon.surface.observed import viewed_area
from recon.surface.provenance import SurfaceEvidence, store_face_provenance
from recon.sfm.cameras import camera_from_colmap, camera_poses
from sim.render.capture_light import ENCODING
from sim.render.provenance import PROVENANCE_FILE
from sim.render.scene import Scene, read_scene_mesh_enu
from sim.render.scene_cameras import SceneCamera, write_cameras
from sim.render.sky import bake_fits, write_scene_sky_visibility
from sim.render.sky_file import FORMAT as SKY_FORMAT, SKY_FILE, StoredSky, read_sky_visibility, write_sky_visibility

SCENE_FORMAT = "aerostereo-scene/1"
CAMERAS_FILE = "cameras.json"
CAPTURE_LIGHT_FILE = "capture_light.png"


def scene_cameras(model: pycolmap.Reconstruction, gains: Mapping[str, float], held_out: Collection[str],
                  capture_suns: Mapping[str, Sequence[float]] | None = None) -> list[SceneCamera]:
    """The registered photos of an SfM ``model`` (full-resolution cameras, ENU metres) in name order, with their
    texture exposure gain (1.0 where ``gains`` has none), whether they were ``held_out``, and their capture sun
    (azimuth, elevation degrees; where ``capture_suns`` has one)."""
    poses, capture_suns = camera_poses(model), capture_suns or {}
    images = sorted((image for image in model.images.values() if image.name in poses), key=lambda i: i.name)
    return [SceneCamera(image.name, camera_from_colmap(image.camera), poses[image.name],
                        float(gains.get(image.name, 1.0)), image.name in held_out,
                        None if image.name not in capture_suns else tuple(map(float, capture_suns[image.name])))
            for image in images]


def scene_metadata(mesh: trimesh.Trimesh, mesh_name: str, origin: LocalFrame, provenance: dict) -> dict:
    """``scene.json`` content for an ENU mesh (no vertex offset): height range and valid area from the mesh; a GLB
    (ours: sim/render/glb.py) is stored +Y up, a PLY as ENU."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    return {
        "format": SCENE_FORMAT,
        "mesh": mesh_name,
        "origin": origin.to_dict(),
        "units": "m",
        "up_axis": "y" if mesh_name.endswith(".glb") else "z",
        "frame": "enu",
        "vertex_offset_m": [0.0, 0.0, 0.0],
        "ground_height_range_m": [float(v[:, 2].min()), float(v[:, 2].max())],
        "valid_area_m": {"xmin": float(v[:, 0].min()), "xmax": float(v[:, 0].max()),
                         "ymin": float(v[:, 1].min()), "ymax": float(v[:, 1].max())},
        "provenance": provenance,
    }


def store_sky_visibility(scene_dir: Path, meta: dict, baked: Path | None = None) -> None:
    """Bake the sky visibility of the mesh that ``meta`` (scene.json's content, the mesh already written) names, read
    as the scene loader reads it, into ``scene_dir/sky_visibility.npz``, and name it in ``meta``. ``baked``: a sky
    visibility file (sim/render/sky_file.py) baked earlier, the texture stage's (:attr:`~recon.appearance.atlas.Atlas
    .sky`), stored instead of a new bake where it was baked from this very mesh with today's settings (the same
    numbers); any other, or an unreadable one, is baked anew."""
    vertices, faces, surface = read_scene_mesh_enu(scene_dir, meta)
    scene = Scene(vertices, faces, surface, source=str(scene_dir))
    earlier = earlier_bake(baked, scene)
    if earlier is None:
        write_scene_sky_visibility(scene_dir / SKY_FILE, scene)
    else:
        write_sky_visibility(scene_dir / SKY_FILE, earlier.visibility, earlier.baked_from)
    meta["sky_visibility"] = {"file": SKY_FILE, "format": SKY_FORMAT}


def earlier_bake(path: Path | None, scene: Scene) -> StoredSky | None:
    """The sky visibility stored at ``path`` where it was baked from ``scene``'s very mesh with today's settings
    (sim.render.sky.bake_fits), else None (no path, no file, another mesh, or a file that cannot be read)."""
    if path is None or not Path(path).is_file():
        return None
    try:
        stored = read_sky_visibility(path)
    except ValueError:
        return None
    return stored if bake_fits(stored, scene) else None


def write_scene(scene_dir: Path, mesh: trimesh.Trimesh, origin: LocalFrame, provenance: dict,
                mesh_name: str = "terrain.ply", encoded: bytes | None = None,
                cameras: Sequence[SceneCamera] = (), capture_light: tuple[bytes, dict] | None = None,
                evidence: SurfaceEvidence | None = None, sky_bake: Path | None = None) -> Path:
    """Write ``mesh_name`` (the ``encoded`` file bytes if given, else ``mesh`` exported by trimesh), ``cameras.json``
    when there are ``cameras``, the ``capture_light`` (PNG bytes, what to say of it) of a delit texture, the mesh's
    sky visibility (:func:`store_sky_visibility`, from the bake in the file ``sky_bake`` where that fits), its faces'
    provenance found from ``evidence`` (None: the mesh is taken as measured everywhere, and no file is left) and
    ``scene.json`` (last, so its presence means the scene is complete). A mesh the scene loader refuses (no texture
    and no vertex colours) is a ``SceneError`` naming it."""
    scene_dir = Path(scene_dir)
    with atomic_path(scene_dir / mesh_name) as tmp:
        if encoded is None:
            mesh.export(tmp)
        else:
            tmp.write_bytes(encoded)
    meta = scene_metadata(mesh, mesh_name, origin, provenance)
    if capture_light is not None:
        png, description = capture_light
        with atomic_path(scene_dir / CAPTURE_LIGHT_FILE) as tmp:
            tmp.write_bytes(png)
        meta["capture_light"] = {"file": CAPTURE_LIGHT_FILE, "encoding": ENCODING, **description}
    else:  # a rerun that keeps the light leaves no capture light of an earlier run beside the lit texture
        (scene_dir / CAPTURE_LIGHT_FILE).unlink(missing_ok=True)
    if cameras:
        write_cameras(scene_dir / CAMERAS_FILE, cameras)
        meta["cameras"] = CAMERAS_FILE
        if len(cameras) >= 3:
            ground_z = float(np.median(np.asarray(mesh.vertices)[:, 2]))
            area = viewed_area(np.array([camera.T_world_cam for camera in cameras]), ground_z)
            meta["observed_area_m"] = area.round(3).tolist()
    store_sky_visibility(scene_dir, meta, sky_bake)
    if evidence is not None:
        store_face_provenance(scene_dir, meta, evidence)
    else:
        (scene_dir / PROVENANCE_FILE).unlink(missing_ok=True)
    write_text_atomic(scene_dir / "scene.json", json.dumps(meta, indent=2))
    return scene_dir / "scene.json"
