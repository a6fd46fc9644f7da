"""Scenes: a triangle mesh with its texture in local ENU metres, recentred and built into embree once.

A scene folder holds ``scene.json``, the mesh it names and, for a reconstruction, the ``cameras.json`` it names
(its registered photos, sim/render/scene_cameras.py; see docs/interfaces.md). Vertices are converted
in float64 (``ENU = stored - vertex_offset_m``, glTF +Y-up rotated to ENU: our GLBs say so in their
``scenes[0].extras`` georeference, sim/render/glb.py; other meshes by scene.json's ``up_axis``), then *recentred* on the
mesh's bounding-box centre and only then cast to float32 for embree: float32 has ~0.5 m spacing at
UTM northings, a few micrometres near the origin.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import trimesh
from embreex import mesh_construction, rtcore, rtcore_scene
from PIL import Image

from cliutil.errors import BadInput
from flightplan.geodesy import LocalFrame
from cliutil.jsonfile import loads_json
from sim.render.capture_light import read_capture_light
from sim.render.labels import SceneLabels, read_labels
from sim.render.provenance import read_face_provenance
from sim.render.mesh_file import check_mesh_file
from sim.render.scene_cameras import CamerasError, SceneCamera, read_cameras
from sim.render.sky_file import SkyVisibility, StoredSky, mesh_sha256, read_sky_visibility
from sim.render.texture import MAX_TEXTURE_SIDE, linear_texture
from sim.render.glb import GEOREF_FORMAT, GEOREF_KEY, enu_from_gltf

SCENE_FORMAT = "aerostereo-scene/1"


@functools.cache
def shared_device() -> rtcore.EmbreeDevice:
    """The one embree device (and TBB thread arena) all scenes of this process use unless given another;
    an embreex scene built without a device would create its own."""
    return rtcore.EmbreeDevice()


class SceneError(ValueError):
    """A scene folder, scene.json or mesh that cannot be used; the message names the file and the problem."""


@dataclass(frozen=True)
class Surface:
    """How a mesh is coloured (all sRGB uint8): one ``texture`` with per-vertex ``uv``; or several ``textures`` (a
    scene of several textured parts, each with its own image) with per-vertex ``uv`` and ``face_texture``, the index
    into ``textures`` of each face; or per-vertex colours. The texture is the albedo. ``capture_light``: for a
    reconstruction whose texture had its capture day's light taken out, that light (linear float32 ``(H, W, 3)`` on
    the texture's UVs), so that albedo x capture light is the texture as photographed."""

    texture: np.ndarray | None = None
    uv: np.ndarray | None = None
    vertex_colors: np.ndarray | None = None
    textures: tuple[np.ndarray, ...] = ()
    face_texture: np.ndarray | None = None
    capture_light: np.ndarray | None = None

    @functools.cached_property
    def linear_texture(self) -> np.ndarray:
        """The texture in linear light, float32 ``(H, W, 3)``: made on first use (renderers), then kept."""
        return linear_texture(self.texture)

    @functools.cached_property
    def linear_textures(self) -> tuple[np.ndarray, ...]:
        """Each of ``textures`` in linear light, float32 ``(H, W, 3)``: made on first use, then kept."""
        return tuple(linear_texture(texture) for texture in self.textures)


@dataclass
class Scene:
    """A ray-castable mesh in local ENU metres.

    ``vertices`` are float64 ENU, ``faces`` int32 (degenerate triangles removed), ``centre_m`` the
    float64 ENU point subtracted before the float32 cast, ``bounds`` the ``(2, 3)`` ENU box
    ``[min, max]`` of the triangles; ``embree`` is the committed embree scene
    in those recentred float32 coordinates. ``origin`` is the geodetic origin of the ENU frame. ``cameras``:
    a reconstruction's registered photos (``cameras.json``; empty for other scenes). ``labels``: the class, object and
    confidence of every face (:mod:`sim.render.labels`; given for the faces as passed in, kept for those left), or
    None for a scene without labels. ``face_provenance``: each face's uint8 provenance code (:mod:`sim.render.provenance`;
    given for the faces as passed in, kept for those left), or None for a scene measured everywhere.
    """

    vertices: np.ndarray
    faces: np.ndarray
    surface: Surface
    origin: LocalFrame | None = None
    valid_area_m: dict | None = None
    source: str = "<memory>"
    cameras: tuple[SceneCamera, ...] = ()
    centre_m: np.ndarray = field(init=False)
    bounds: np.ndarray = field(init=False)
    embree: rtcore_scene.EmbreeScene = field(init=False, repr=False)
    device: rtcore.EmbreeDevice | None = field(default=None, repr=False)
    observed_area_m: list | None = None  # scene.json's [[x, y], ...] ENU polygon (simple, maybe non-convex)
    #: The sky visibility of every face corner; None: taken from ``stored_sky`` or baked on the first lit render
    #: (sim.render.sky.scene_sky_visibility).
    sky_visibility: SkyVisibility | None = None
    #: The sky visibility the scene folder stores (scene.json's ``sky_visibility``), used only if baked from this mesh.
    stored_sky: StoredSky | None = field(default=None, repr=False)
    #: Where a bake is stored for the renders after this one (scene.json's ``sky_visibility`` marked ``"cache"``:
    #: a demo world's folder); None: a bake stays in memory.
    sky_cache: Path | None = field(default=None, repr=False)
    #: ``(F, 3)`` float32 unit normals of the faces' winding (which side of a face is its front).
    face_normals: np.ndarray = field(init=False, repr=False)
    #: Which of the faces given the scene kept (bool, one per face given): the zero-area ones are left out.
    kept_faces: np.ndarray = field(init=False, repr=False)
    labels: SceneLabels | None = field(default=None, repr=False)
    face_provenance: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self.vertices = np.asarray(self.vertices, dtype=np.float64)
        if self.vertices.ndim != 2 or self.vertices.shape[1] != 3 or not np.all(np.isfinite(self.vertices)):
            raise SceneError(f"{self.source}: vertices must be a finite (N, 3) array")
        faces = np.asarray(self.faces, dtype=np.int64).reshape(-1, 3)
        if len(faces) == 0 or faces.min() < 0 or faces.max() >= len(self.vertices):
            raise SceneError(f"{self.source}: faces must index the {len(self.vertices)} vertices")
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        self.centre_m = (lo + hi) / 2.0
        local32 = (self.vertices - self.centre_m).astype(np.float32)
        kept = self.kept_faces = _non_degenerate(local32, faces)
        self.faces = faces[kept].astype(np.int32)
        if len(self.faces) == 0:
            raise SceneError(f"{self.source}: every triangle is degenerate (zero area)")
        used = self.vertices[np.unique(self.faces)]
        self.bounds = np.stack([used.min(axis=0), used.max(axis=0)])
        self.surface = _checked_surface(self.surface, len(self.vertices), kept, self.source)
        if self.labels is not None:
            if len(self.labels) != len(kept):
                raise SceneError(f"{self.source}: labels for {len(self.labels)} faces, the mesh has {len(kept)}")
            self.labels = self.labels.subset(kept)
        if self.face_provenance is not None:
            if len(self.face_provenance) != len(kept):
                raise SceneError(f"{self.source}: face provenance for {len(self.face_provenance)} faces, the mesh has "
                                 f"{len(kept)}")
            self.face_provenance = np.asarray(self.face_provenance, dtype=np.uint8)[kept]
        self.face_normals = unit_face_normals(local32, self.faces).astype(np.float32)
        self.device = self.device or shared_device()
        self.embree = rtcore_scene.EmbreeScene(device=self.device, robust=True)
        mesh_construction.TriangleMesh(self.embree, local32, self.faces)
        # embreex commits lazily and unguarded on the first run(): commit here, before threads share it.
        self.embree.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32))

    @property
    def valid_area(self) -> tuple[float, float, float, float]:
        """ENU rectangle ``(xmin, xmax, ymin, ymax)`` (metres) with real content: ``valid_area_m`` from
        scene.json, else the mesh footprint. This and :meth:`ground_height` make a Scene a pose-sampler
        ``GroundModel`` (sim/sampling/pose.py)."""
        if self.valid_area_m is not None:
            return tuple(float(self.valid_area_m[key]) for key in ("xmin", "xmax", "ymin", "ymax"))
        (xmin, ymin, _), (xmax, ymax, _) = self.bounds
        return float(xmin), float(xmax), float(ymin), float(ymax)

    def to_local(self, points_enu: np.ndarray) -> np.ndarray:
        """ENU points (float64) -> recentred float32 coordinates used by embree."""
        return (np.asarray(points_enu, dtype=np.float64) - self.centre_m).astype(np.float32)

    def ground_height(self, east_m, north_m) -> np.ndarray:
        """ENU height (m) of the topmost surface under each (east, north); NaN where there is no surface."""
        east, north = np.broadcast_arrays(np.asarray(east_m, np.float64), np.asarray(north_m, np.float64))
        top = self.bounds[1, 2] + 1.0
        origins = np.stack([east.ravel(), north.ravel(), np.full(east.size, top)], axis=-1)
        t = self.embree.run(self.to_local(origins), np.array([[0, 0, -1]], np.float32), query="DISTANCE")
        height = np.where(t < 1e30, top - t.astype(np.float64), np.nan)
        return height.reshape(east.shape)


def _checked_surface(surface: Surface, n_vertices: int, kept: np.ndarray, source: str) -> Surface:
    """The surface with float32 (column-major) UVs and, for several textures, the texture index of the faces
    ``kept`` (a mask over the faces it was made for), after checking it colours every vertex and face."""
    if surface.texture is not None and surface.textures:
        raise SceneError(f"{source}: give one texture or several (textures with face_texture), not both")
    textures = surface.textures or ((surface.texture,) if surface.texture is not None else ())
    if textures:
        # Column-major: renderers gather U and V separately, each from one contiguous column.
        uv = np.asfortranarray(surface.uv, dtype=np.float32) if surface.uv is not None else None
        if uv is None or uv.shape != (n_vertices, 2) or any(t.ndim != 3 or t.dtype != np.uint8 for t in textures):
            raise SceneError(f"{source}: a texture needs (H, W, 3) uint8 pixels and one UV per vertex")
        for texture in textures:
            if max(texture.shape[:2]) > MAX_TEXTURE_SIDE:
                height, width = texture.shape[:2]
                raise SceneError(f"{source}: texture of {width}x{height} px; the renderer samples at most "
                                 f"{MAX_TEXTURE_SIDE} px a side (split or downscale it)")
        if surface.texture is not None:
            return Surface(texture=surface.texture, uv=uv, capture_light=_checked_capture_light(surface, source))
        if surface.capture_light is not None:
            raise SceneError(f"{source}: a capture light needs one texture, not several")
        return Surface(uv=uv, textures=tuple(textures),
                       face_texture=_checked_face_texture(surface.face_texture, len(textures), kept, source))
    if surface.capture_light is not None:
        raise SceneError(f"{source}: a capture light lies on a texture's UVs, and this mesh has no texture")
    colors = surface.vertex_colors
    if colors is None or colors.shape != (n_vertices, 3) or colors.dtype != np.uint8:
        raise SceneError(f"{source}: need a texture with UVs or (N, 3) uint8 vertex colours for all {n_vertices} vertices")
    return surface


def _checked_capture_light(surface: Surface, source: str) -> np.ndarray | None:
    """The surface's capture light as float32 ``(H, W, 3)``, after checking it is finite and non-negative."""
    light = surface.capture_light
    if light is None:
        return None
    light = np.asarray(light, dtype=np.float32)
    if light.ndim != 3 or light.shape[2] != 3 or not np.all(np.isfinite(light)) or light.min() < 0:
        raise SceneError(f"{source}: a capture light must be a finite, non-negative (H, W, 3) image")
    if max(light.shape[:2]) > MAX_TEXTURE_SIDE:
        raise SceneError(f"{source}: capture light of {light.shape[1]}x{light.shape[0]} px; the renderer samples at "
                         f"most {MAX_TEXTURE_SIDE} px a side")
    return light


def _checked_face_texture(index: np.ndarray | None, n_textures: int, kept: np.ndarray, source: str) -> np.ndarray:
    """The texture index (int32) of the faces ``kept`` (a mask over all faces), after checking ``index`` gives one
    texture in ``[0, n_textures)`` per face."""
    index = None if index is None else np.asarray(index)
    if (index is None or index.shape != kept.shape or not np.issubdtype(index.dtype, np.integer)
            or index.min() < 0 or index.max() >= n_textures):
        raise SceneError(f"{source}: several textures need face_texture, one index in [0, {n_textures}) per face "
                         f"({len(kept)} faces)")
    return np.ascontiguousarray(index[kept], dtype=np.int32)


def unit_face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(F, 3)`` float64 unit normals of the triangles' winding (right-handed: v0, v1, v2 counter-clockwise; embree's
    geometric normal points the same way), 0 for a zero-area triangle."""
    corners = np.asarray(vertices, dtype=np.float64)[faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)


def _non_degenerate(local32: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Mask of the faces whose float32 triangle has non-zero area (zero-area ones are never hit and have no
    normal)."""
    tri = local32[faces].astype(np.float64)
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    return np.einsum("ij,ij->i", cross, cross) > 0


def read_scene_json(scene_dir: Path, labels: bool = True, provenance: bool = True) -> dict:
    """Parse and check ``scene_dir/scene.json``; raise :class:`SceneError` naming the file and field. ``labels``
    False: without its ``labels`` entry, left unchecked (for what renders no class or object images: a broken entry
    must not refuse a depth render); ``provenance`` False: the same for its ``face_provenance`` entry."""
    path = Path(scene_dir) / "scene.json"
    if not path.is_file():
        raise SceneError(f"{path}: scene.json not found (a scene folder needs scene.json and its mesh)")
    try:
        meta = loads_json(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SceneError(f"{path}: not valid UTF-8 JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise SceneError(f"{path}: expected a JSON object {{\"format\": \"{SCENE_FORMAT}\", ...}}, "
                         f"got a {type(meta).__name__}")
    if not labels:
        meta.pop("labels", None)
    if not provenance:
        meta.pop("face_provenance", None)
    if meta.get("format") != SCENE_FORMAT:
        raise SceneError(f"{path}: expected \"format\": \"{SCENE_FORMAT}\", got {meta.get('format')!r}")
    for key, expected in (("units", "m"), ("frame", "enu")):
        if meta.get(key, expected) != expected:
            raise SceneError(f"{path}: \"{key}\" must be {expected!r}, got {meta[key]!r}")
    if meta.get("up_axis", "z") not in ("z", "y"):
        raise SceneError(f"{path}: \"up_axis\" must be \"z\" or \"y\", got {meta['up_axis']!r}")
    offset = meta.get("vertex_offset_m", [0.0, 0.0, 0.0])
    if not (isinstance(offset, list) and len(offset) == 3 and all(isinstance(c, (int, float)) for c in offset)):
        raise SceneError(f"{path}: \"vertex_offset_m\" must be a list of 3 numbers, got {offset!r}")
    area = meta.get("valid_area_m")
    if area is not None and not _is_rectangle(area):
        raise SceneError(f"{path}: \"valid_area_m\" must be {{xmin, xmax, ymin, ymax}} numbers with min < max, got {area!r}")
    observed = meta.get("observed_area_m")
    if observed is not None and not _is_polygon(observed):
        raise SceneError(f"{path}: \"observed_area_m\" must be a list of at least 3 [x, y] number pairs, "
                         f"got {observed!r}")
    if not isinstance(meta.get("mesh"), str):
        raise SceneError(f"{path}: \"mesh\" must name the mesh file")
    if not isinstance(meta.get("cameras", ""), str):
        raise SceneError(f"{path}: \"cameras\" must name the cameras file (cameras.json)")
    named = [("mesh", meta["mesh"]), ("cameras", meta.get("cameras"))]
    for key in ("capture_light", "sky_visibility", "labels", "face_provenance"):
        entry = meta.get(key)
        if entry is not None and not (isinstance(entry, dict) and isinstance(entry.get("file"), str)):
            raise SceneError(f"{path}: \"{key}\" must be {{\"file\": NAME, ...}}, got {entry!r}")
        named.append((f"{key}.file", None if entry is None else entry["file"]))
    for key, name in named:
        if name is not None:
            _require_inside(Path(scene_dir), name, f"{path}: \"{key}\"")
    try:
        meta["origin_frame"] = LocalFrame.from_dict(meta["origin"])
    except (KeyError, TypeError, ValueError) as exc:
        raise SceneError(f"{path}: \"origin\" needs lat0_deg, lon0_deg, h0_ellipsoid_m ({exc})") from None
    return meta


def _require_inside(scene_dir: Path, name: str, where: str) -> None:
    """Refuse a file name that leaves the scene folder (absolute, ``..``, or a link out): a scene folder is
    self-contained, so copying it copies the scene and loading it reads nothing else."""
    folder = scene_dir.resolve()
    if Path(name).is_absolute() or not (folder / name).resolve().is_relative_to(folder):
        raise SceneError(f"{where} {name!r} is outside the scene folder; name a file inside {scene_dir}")


def _is_rectangle(area) -> bool:
    """True for a mapping with numeric xmin < xmax and ymin < ymax."""
    keys = ("xmin", "xmax", "ymin", "ymax")
    if not isinstance(area, dict) or not all(isinstance(area.get(k), (int, float)) for k in keys):
        return False
    return area["xmin"] < area["xmax"] and area["ymin"] < area["ymax"]


def _is_polygon(points) -> bool:
    """True for a list of at least 3 ``[x, y]`` finite number pairs."""
    return (isinstance(points, list) and len(points) >= 3
            and all(isinstance(p, list) and len(p) == 2 and all(isinstance(c, (int, float)) for c in p)
                    and all(np.isfinite(p)) for p in points))


def load_scene(scene_dir, device: rtcore.EmbreeDevice | None = None, labels: SceneLabels | None = None,
               with_labels: bool = True, with_provenance: bool = True) -> Scene:
    """Load a scene folder (``scene.json`` + mesh) into a ray-castable :class:`Scene`.

    Scenes share :func:`shared_device` unless another ``device`` is given. ``labels``: labels of every face of the
    mesh file to use instead of the ones scene.json names (a labeller's, not yet written). ``with_labels`` False:
    the face labels scene.json names are neither read nor checked (the scene has none). ``with_provenance`` False:
    the same for its face provenance (the scene is then taken as measured everywhere).
    """
    scene_dir = Path(scene_dir)
    meta = read_scene_json(scene_dir, labels=with_labels, provenance=with_provenance)
    vertices, faces, surface = read_scene_mesh_enu(scene_dir, meta)
    if "capture_light" in meta:
        surface = replace(surface, capture_light=read_scene_capture_light(scene_dir, meta))
    return Scene(vertices, faces, surface, meta["origin_frame"], meta.get("valid_area_m"),
                 str(scene_dir / meta["mesh"]), read_scene_cameras(scene_dir, meta), device=device,
                 observed_area_m=meta.get("observed_area_m"), stored_sky=read_scene_sky_visibility(scene_dir, meta),
                 sky_cache=scene_sky_cache(scene_dir, meta),
                 labels=labels if labels is not None else read_scene_labels(scene_dir, meta, vertices, faces),
                 face_provenance=read_scene_face_provenance(scene_dir, meta, vertices, faces))


def read_scene_labels(scene_dir: Path, meta: dict, vertices: np.ndarray, faces: np.ndarray) -> SceneLabels | None:
    """The face labels ``scene.json`` (``meta``) names, for the mesh ``vertices`` and ``faces`` as read
    (:func:`read_scene_mesh_enu`); None where it names none. A file that is missing, unreadable or made for another
    mesh is a :class:`SceneError` naming scene.json and its ``labels`` entry."""
    return _read_mesh_file(scene_dir, meta, "labels", read_labels, vertices, faces,
                           f"labels another mesh than {meta.get('mesh')} (its SHA-256 differs); label the scene again "
                           f"(aerostereo-recon labels {scene_dir})")


def read_scene_face_provenance(scene_dir: Path, meta: dict, vertices: np.ndarray,
                               faces: np.ndarray) -> np.ndarray | None:
    """The face provenance codes ``scene.json`` (``meta``) names, for the mesh ``vertices`` and ``faces`` as read
    (:func:`read_scene_mesh_enu`); None (measured everywhere) where it names none. A file that is missing, unreadable
    or made for another mesh is a :class:`SceneError` naming scene.json and its ``face_provenance`` entry."""
    return _read_mesh_file(scene_dir, meta, "face_provenance", read_face_provenance, vertices, faces,
                           f"describes another mesh than {meta.get('mesh')} (its SHA-256 differs); write the scene "
                           f"again (aerostereo-recon redoes its scene stage once "
                           f"{Path(scene_dir) / 'work' / 'stages' / 'scene.json'} is deleted)")


def _read_mesh_file(scene_dir: Path, meta: dict, key: str, read, vertices: np.ndarray, faces: np.ndarray,
                    other_mesh: str):
    """What the per-face file of ``scene.json``'s entry ``key`` holds, read by ``read(path) -> (content, the SHA-256
    of the mesh it was made for)``; None where scene.json names none. A missing or unreadable file, or one made for
    another mesh than ``vertices``/``faces`` (then ``other_mesh`` says what to do), is a :class:`SceneError`."""
    if key not in meta:
        return None
    name = meta[key]["file"]
    path, entry = Path(scene_dir) / name, f"{Path(scene_dir) / 'scene.json'}: \"{key}\""
    if not path.is_file():
        raise SceneError(f"{entry}: its file {name!r} is not found in {scene_dir}")
    try:
        content, its_mesh = read(path)
    except ValueError as error:
        raise SceneError(f"{entry}: {error}") from None
    if its_mesh != mesh_sha256(vertices, faces):
        raise SceneError(f"{entry}: {path} {other_mesh}")
    return content


def read_scene_sky_visibility(scene_dir: Path, meta: dict) -> StoredSky | None:
    """The sky visibility that ``scene.json`` (``meta``) names (:mod:`sim.render.sky_file`); None where it names none
    or the file is absent (the first lit render bakes it). A file that cannot be read is a :class:`SceneError`,
    except in a cache (:func:`scene_sky_cache`), which the next bake replaces."""
    if "sky_visibility" not in meta:
        return None
    path = Path(scene_dir) / meta["sky_visibility"]["file"]
    if not path.is_file():
        return None
    try:
        return read_sky_visibility(path)
    except ValueError as error:
        if scene_sky_cache(scene_dir, meta) is not None:
            return None
        raise SceneError(f"{error}; delete it and renders bake the sky visibility themselves") from None


def scene_sky_cache(scene_dir: Path, meta: dict) -> Path | None:
    """The file a render stores its sky visibility bake in: the one ``scene.json`` (``meta``) names where its entry
    says ``"cache": true`` (the first lit render bakes it, the later ones load it); else None."""
    entry = meta.get("sky_visibility")
    return Path(scene_dir) / entry["file"] if entry is not None and entry.get("cache") is True else None


def read_scene_capture_light(scene_dir: Path, meta: dict) -> np.ndarray:
    """The capture light that ``scene.json`` (``meta``) names (:mod:`sim.render.capture_light`)."""
    path = Path(scene_dir) / meta["capture_light"]["file"]
    if not path.is_file():
        raise SceneError(f"{path}: capture light file not found (scene.json names it)")
    try:
        return read_capture_light(path)
    except ValueError as error:
        raise SceneError(str(error)) from None


def read_scene_cameras(scene_dir: Path, meta: dict) -> tuple[SceneCamera, ...]:
    """The cameras of the ``cameras.json`` that ``scene.json`` (``meta``) names; none if it names none."""
    if "cameras" not in meta:
        return ()
    try:
        return read_cameras(Path(scene_dir) / meta["cameras"])
    except CamerasError as error:
        raise SceneError(str(error)) from None


def read_scene_mesh_enu(scene_dir: Path, meta: dict) -> tuple[np.ndarray, np.ndarray, Surface]:
    """The mesh of a scene folder in the scene's ENU metres (its up axis, see :func:`mesh_up_axis`, and the
    ``vertex_offset_m`` of its ``scene.json`` ``meta`` applied): float64 vertices, faces and :class:`Surface`."""
    path = Path(scene_dir) / meta["mesh"]
    vertices, faces, surface, georef = read_mesh(path)
    if mesh_up_axis(meta, georef, path) == "y":
        vertices = enu_from_gltf(vertices)
    return vertices - np.asarray(meta.get("vertex_offset_m", [0, 0, 0]), dtype=np.float64), faces, surface


def mesh_up_axis(meta: dict, georef: dict | None, path: Path) -> str:
    """"y" (glTF: x east, y up, z south) or "z" (ENU) for the mesh file at ``path``: a GLB with our georeference
    ``georef`` is +Y up; a mesh without one (older demo worlds and reconstructions: ENU, z up; foreign files) is
    what scene.json's ``up_axis`` says (default "z"). Raise :class:`SceneError` where the two disagree."""
    if georef is None:
        return meta.get("up_axis", "z")
    if not isinstance(georef, dict) or georef.get("format") != GEOREF_FORMAT:
        raise SceneError(f"{path}: scenes[0].extras.{GEOREF_KEY} must have \"format\": \"{GEOREF_FORMAT}\", "
                         f"got {georef!r}")
    if meta.get("up_axis", "y") != "y":
        raise SceneError(f"{path}: the GLB says it is +Y up ({GEOREF_KEY}) but scene.json says "
                         f"\"up_axis\": {meta['up_axis']!r}")
    if georef.get("origin") != meta["origin"]:
        raise SceneError(f"{path}: the GLB's georeference origin {georef.get('origin')} is not scene.json's "
                         f"origin {meta['origin']}")
    return "y"


def read_mesh(path: Path) -> tuple[np.ndarray, np.ndarray, Surface, dict | None]:
    """Read a mesh file with trimesh -> float64 vertices (as stored), faces, its :class:`Surface` and its
    aerostereo georeference (``scenes[0].extras`` of a GLB written by sim/render/glb.py; None for other files).

    A file of several textured geometries (a multi-part GLB, sim/render/glb.py, or any scene trimesh loads so) is
    read part by part, each placed by its node transform and keeping its own texture (:func:`_parts_surface`);
    any other file is joined into one mesh by trimesh."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: mesh file not found")
    try:
        check_mesh_file(path, MAX_TEXTURE_SIDE)
    except BadInput as error:  # declares more than can be loaded, or more than this machine's memory holds
        raise SceneError(str(error)) from None
    try:
        loaded = trimesh.load(path, force="scene", process=False)
        georef = loaded.metadata.get(GEOREF_KEY)
        if _textured_parts(loaded):
            return (*_parts_surface(loaded.dump()), georef)
        mesh = loaded.to_mesh()
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise SceneError(f"{path}: trimesh cannot read this mesh ({type(exc).__name__}: {exc})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise SceneError(f"{path}: no triangles found")
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces), _surface_of(mesh, path), georef


def _textured_parts(loaded: trimesh.Scene) -> bool:
    """Whether a loaded scene places more than one geometry and every geometry has a texture image with UVs: joining
    them in one mesh would make trimesh pack their images into one."""
    geometries = list(loaded.geometry.values())
    return len(loaded.graph.nodes_geometry) > 1 and all(
        isinstance(g, trimesh.Trimesh) and _texture_of(g) is not None for g in geometries)


def _parts_surface(meshes: list[trimesh.Trimesh]) -> tuple[np.ndarray, np.ndarray, Surface]:
    """Float64 vertices, faces and a several-texture :class:`Surface` of textured ``meshes`` (already placed by
    their node transforms, trimesh's ``Scene.dump``) concatenated in order, face ``f`` of part ``k`` textured by
    texture ``k``."""
    offsets = np.cumsum([0] + [len(mesh.vertices) for mesh in meshes])
    faces = np.concatenate([np.asarray(mesh.faces) + offset for mesh, offset in zip(meshes, offsets)])
    textures, uvs = zip(*(_texture_of(mesh) for mesh in meshes))
    face_texture = np.repeat(np.arange(len(meshes)), [len(mesh.faces) for mesh in meshes])
    vertices = np.concatenate([np.asarray(mesh.vertices, dtype=np.float64) for mesh in meshes])
    return vertices, faces, Surface(uv=np.concatenate(uvs), textures=textures, face_texture=face_texture)


def _texture_of(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray] | None:
    """The sRGB uint8 ``(H, W, 3)`` texture and float64 ``(N, 2)`` UVs of a mesh, if it has both."""
    visual = mesh.visual
    if isinstance(visual, trimesh.visual.TextureVisuals):
        image = _material_image(visual.material)
        uv = visual.uv
        if image is not None and uv is not None and len(uv) == len(mesh.vertices):
            texture = np.ascontiguousarray(np.asarray(image.convert("RGB"), dtype=np.uint8))
            return texture, np.asarray(uv, dtype=np.float64)
    return None


def _surface_of(mesh: trimesh.Trimesh, path: Path) -> Surface:
    """Texture + UVs if the mesh has both, else vertex colours, else a clear error."""
    textured = _texture_of(mesh)
    if textured is not None:
        return Surface(texture=textured[0], uv=textured[1])
    visual = mesh.visual
    if visual.kind == "vertex":
        colors = np.asarray(visual.vertex_colors)
        return Surface(vertex_colors=np.ascontiguousarray(colors[:, :3], dtype=np.uint8))
    raise SceneError(
        f"{path}: mesh has no texture with UVs and no vertex colours "
        "(need an image texture with per-vertex UVs, or per-vertex RGB colours)"
    )


def _material_image(material) -> Image.Image | None:
    """The base-colour image of a trimesh material (Simple or PBR), if any."""
    for name in ("image", "baseColorTexture"):
        image = getattr(material, name, None)
        if isinstance(image, Image.Image):
            return image
    return None
