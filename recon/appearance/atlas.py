"""Texture a 3-D mesh with an atlas: each face charted in the best photo that sees it, coloured from all that see it.

The approach of Waechter, Moehrle and Goesele, "Let there be color!" (mvs-texturing), small: frames are the scene's
ENU metres for the mesh and undistorted pinhole photos (:class:`recon.appearance.texture.Photo`, OpenCV axes,
``T_world_cam`` in the same frame).

1. **Candidate views** per face: the ``candidates`` best photos in which the face's centroid is in front, inside the
   image, facing the camera and not occluded (an embree occlusion ray from the camera centre). Quality is the face's
   projected area per square metre of surface, ``(f / d)^2 cos(angle)``: resolution and viewing angle in one number.
2. **Labelling**: one photo per face, minimising a data cost (``1 - quality / best quality of that face``) plus a
   Potts penalty ``smoothness`` for every edge neighbour on another photo (iterated conditional modes, alternating
   halves of the faces so that neighbours never flip together): neighbouring faces stay on one photo where quality
   allows, so seams are few.
3. **Charts**: connected faces on the same photo form a patch whose UVs are its projection into that photo (no
   distortion beyond the view's own); a face no photo sees is a chart of its own, flattened in its plane. xatlas
   packs the charts into one atlas at ``1 / texel_m`` texels per metre, with a gutter of ``padding_px``.
4. **Exposure**: per-photo gains (linear light, geometric mean 1) solved globally from the candidates' colours at
   shared face centroids (:func:`recon.appearance.texture.solve_log_gains`) and applied to every sample.
5. **Texels**: each texel inside a face (or in the gutter beside it) gets that face's 3-D point (barycentric,
   clamped to the triangle), projected into the face's candidate photos that see all three of its corners (its own
   photo always, where its image holds the point) and sampled bilinearly in linear light, times each photo's gain;
   the texel is their mean weighted by ``(quality / best quality)^blend_power`` (default 1: in proportion to the
   pixels each photo puts on the face).
   The best view weighs most, and the others average out the sensor noise and the view-dependent look that a new
   view would not share (held-out real photos: p4m_rtk 4.45 -> 4.14 % with power 4; brighton_beach, every third
   photo held out, 5.06 -> 4.86 % with power 1; docs/recon.md). Texels of faces no photo sees, and texels no photo
   holds, take the nearest coloured texel.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import cv2
import numpy as np
import trimesh
import xatlas
from PIL import Image
from scipy import ndimage, sparse

from flightplan.geodesy import LocalFrame
from recon.appearance.delight import CaptureSetup, Delighting, TexelLight, delight_atlas
from recon.appearance.texture import JPEG_QUALITY, Photo, solve_log_gains
from recon.surface.mesh import scene_from_mesh
from sim.render.camera import PinholeCamera, project_world_points, row_dots
from sim.render.raycast import occluded
from sim.render.scene import Scene
from sim.render.sky_file import SkyVisibility
from sim.render.texture import linear_texture, sample_linear
from sim.render.color import to_srgb8
from sim.render.glb import encode_textured_glb, stored_positions

#: Sub-pixel bits of the face rasteriser (OpenCV ``shift``).
RASTER_SHIFT = 4
#: Texels per chunk when turning texels into surface points (bounds the memory of the barycentric step).
TEXEL_CHUNK = 1 << 20


@dataclass(frozen=True)
class AtlasOptions:
    """``texel_m`` None = one pixel of the photos on the surface (:func:`photo_pixel_m`; the atlas shrinks
    uniformly when that would exceed ``max_texture_px`` on a side); ``candidates`` best views kept per face; ``smoothness`` Potts penalty per
    neighbour on another photo (data costs are in [0, 1]); ``border_px`` how far inside the image a face's centroid
    must project; ``gain_faces`` faces sampled for the exposure gains, ``min_overlap`` of them shared for a photo
    pair to count; ``padding_px`` gutter between charts; ``blend_power`` sharpens the blend of a face's views
    (``inf``: its own photo alone)."""

    texel_m: float | None = None
    max_texture_px: int = 8192
    candidates: int = 6
    smoothness: float = 0.3
    iterations: int = 30
    border_px: float = 4.0
    balance_exposure: bool = True
    gain_faces: int = 20000
    min_overlap: int = 30
    padding_px: int = 2
    blend_power: float = 1.0

    def __post_init__(self) -> None:
        if self.texel_m is not None and not (np.isfinite(self.texel_m) and self.texel_m > 0):
            raise ValueError(f"texel size must be a positive number of metres, got {self.texel_m}")
        if self.candidates < 1:
            raise ValueError(f"candidates must be at least 1, got {self.candidates}")
        if not self.blend_power > 0:
            raise ValueError(f"blend power must be positive (inf: one photo per face), got {self.blend_power}")


@dataclass(frozen=True)
class FaceViews:
    """The best photos of every face, best first: ``view`` (F, K) photo indices (-1: none) and ``quality`` (F, K),
    projected pixels per square metre of surface (0 where none)."""

    view: np.ndarray
    quality: np.ndarray


@dataclass(frozen=True)
class Atlas:
    """A textured mesh: ``vertices`` (M, 3) ENU metres (split where charts meet), ``faces`` (F, 3) in the input mesh's
    face order, ``uv`` (M, 2) with v up (OBJ/trimesh convention), ``image`` (H, W, 3) uint8 sRGB; per face its photo
    ``labels`` (index into the photos, -1: none saw it) and ``face_seen``, whether photos hold most of its texels
    (:func:`photographed_faces`); per photo name its exposure ``gains`` (texture = gain x photo, linear light; held-out
    photos included); ``coverage`` the fraction of the surface area some photo sees. With the capture suns: ``image`` is
    the albedo, ``capture_light`` (H, W, 3) float32 linear the light it was divided by (None: nothing was divided out),
    ``delighting`` what was done, and ``sky`` the sky visibility baked to do it with what it was baked from: the bake of
    the scene this atlas's GLB makes (:meth:`~recon.appearance.delight.CaptureSetup.scene_bake`), which the scene folder
    stores rather than bake it again. The ``vertices`` are what the GLB stores (float32 values,
    sim.render.glb.stored_positions)."""

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    image: np.ndarray
    labels: np.ndarray
    face_seen: np.ndarray
    gains: dict[str, float]
    coverage: float
    texel_m: float
    capture_light: np.ndarray | None = None
    delighting: Delighting | None = None
    sky: tuple[SkyVisibility, dict] | None = None

    def glb(self, origin: LocalFrame, generator: str = "recon.atlas") -> bytes:
        """Binary glTF of the textured mesh (ENU metres at ``origin``, stored +Y up and georeferenced by
        sim/render/glb.py), the atlas embedded as JPEG."""
        buffer = io.BytesIO()
        Image.fromarray(self.image).save(buffer, format="JPEG", quality=JPEG_QUALITY, subsampling=0)
        return encode_textured_glb(self.vertices, self.faces, self.uv, buffer.getvalue(), generator, origin)


# ---------------------------------------------------------------- 1. candidate views


def in_image(camera: PinholeCamera, pixels: np.ndarray, depth: np.ndarray, border_px: float = 0.0) -> np.ndarray:
    """True where projected points (``pixels`` (N, 2), ``depth`` (N,): :func:`project_world_points`) lie in front of
    ``camera`` and at least ``border_px`` inside its image."""
    x, y = pixels[:, 0], pixels[:, 1]
    return ((depth > 0) & (x >= border_px) & (x <= camera.width - 1 - border_px) & (y >= border_px)
            & (y <= camera.height - 1 - border_px))


def unoccluded(scene: Scene, centre: np.ndarray, towards: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """True where nothing lies between a camera ``centre`` (3,) and the points ``distance`` (N,) metres along the unit
    rays ``towards`` (N, 3) from it (ENU), short of each point by max(5 cm, 0.2 % of its distance): the point's own
    surface must not hide it."""
    tolerance = np.maximum(0.05, 2e-3 * distance)
    return ~occluded(scene, np.asarray(centre, dtype=np.float64)[None, :], towards, distance - tolerance)


def visible_faces(scene: Scene, centroids: np.ndarray, normals: np.ndarray, photo: Photo,
                  border_px: float, wanted_above: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Faces whose centroid ``photo`` sees (in front, ``border_px`` inside the image, not edge-on, not occluded)
    and their quality ``(f / d)^2 |cos|`` (the mesh may be two-sided: either face side counts). With
    ``wanted_above`` (F,), only the faces whose quality in this photo exceeds it are looked for: the others cast no
    occlusion ray."""
    cam, T = photo.camera, np.asarray(photo.T_world_cam, dtype=np.float64)
    pixels, depth = project_world_points(cam, T, centroids)
    inside = np.flatnonzero(in_image(cam, pixels, depth, border_px))
    if wanted_above is not None:  # a quality is at most (f / z)^2: the distance is at least the planar depth z
        inside = inside[(cam.fx / depth[inside]) ** 2 > wanted_above[inside]]
    to_camera = T[:3, 3] - centroids[inside]
    distance = np.sqrt(row_dots(to_camera, to_camera))
    direction = to_camera / distance[:, None]
    cosine = np.abs(row_dots(direction, normals[inside]))
    quality = cosine * (cam.fx / distance) ** 2
    facing = cosine > 0.05
    if wanted_above is not None:
        facing &= quality > wanted_above[inside]
    inside, distance, direction, quality = inside[facing], distance[facing], direction[facing], quality[facing]
    seen = unoccluded(scene, T[:3, 3], -direction, distance)
    return inside[seen], quality[seen]


def face_candidates(scene: Scene, mesh: trimesh.Trimesh, photos: list[Photo], options: AtlasOptions,
                    progress=lambda it: it) -> FaceViews:
    """The ``options.candidates`` best photos of every face of ``mesh`` (see :func:`visible_faces`). A photo is
    looked for only on the faces where it would beat the weakest candidate so far: most of the default orbit's 450
    photos see a face worse than the nearer photos before them, and those cast no occlusion ray (the same candidates
    in 69 s against 140 s, quiet)."""
    centroids, normals = np.asarray(mesh.triangles_center), np.asarray(mesh.face_normals)
    view = np.full((len(centroids), options.candidates), -1, np.int32)
    quality = np.zeros((len(centroids), options.candidates))
    weakest_quality = np.zeros(len(centroids))
    for index, photo in enumerate(progress(photos)):
        faces, q = visible_faces(scene, centroids, normals, photo, options.border_px, weakest_quality)
        weakest = quality[faces].argmin(axis=1)
        view[faces, weakest] = index
        quality[faces, weakest] = q
        weakest_quality[faces] = quality[faces].min(axis=1)
    order = np.argsort(-quality, axis=1, kind="stable")
    return FaceViews(np.take_along_axis(view, order, axis=1), np.take_along_axis(quality, order, axis=1))


def corners_seen(scene: Scene, mesh: trimesh.Trimesh, photos: list[Photo], views: FaceViews) -> np.ndarray:
    """(F, K) True where candidate ``views.view[f, k]`` sees all three corners of face ``f``: in front of it, inside
    its image and unoccluded (an occlusion ray from the camera centre per photo and corner, with
    :func:`unoccluded`). A candidate is picked by its centroid alone, and a photo that sees a face only
    in part would blend the occluder's colour, or its image's edge, into it."""
    vertices, faces = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)
    seen = np.zeros(views.view.shape, bool)
    for k, photo in enumerate(photos):
        face, slot = np.nonzero(views.view == k)
        if not len(face):
            continue
        corners, where = np.unique(faces[face], return_inverse=True)
        free = in_image(photo.camera, *project_world_points(photo.camera, photo.T_world_cam, vertices[corners]))
        centre = np.asarray(photo.T_world_cam, dtype=np.float64)[:3, 3]
        to_corner = vertices[corners[free]] - centre
        distance = np.sqrt(row_dots(to_corner, to_corner))
        free[free] = unoccluded(scene, centre, to_corner / distance[:, None], distance)
        seen[face, slot] = free[where.reshape(-1, 3)].all(axis=1)
    return seen


def blend_views(views: FaceViews, labels: np.ndarray, seen: np.ndarray) -> FaceViews:
    """The candidates that may colour a face: its ``labels`` photo and the others that see all its corners (``seen``
    (F, K), :func:`corners_seen`)."""
    keep = seen | (views.view == labels[:, None])
    return FaceViews(np.where(keep, views.view, -1), np.where(keep, views.quality, 0.0))


def photo_pixel_m(views: FaceViews) -> float:
    """Median over the seen faces of the side (metres) of one pixel of their best photo on the surface."""
    best = views.quality[:, 0]
    if not (best > 0).any():
        raise ValueError("no photo sees the mesh: wrong poses or frame?")
    return float(np.median(1.0 / np.sqrt(best[best > 0])))


# ---------------------------------------------------------------- 2. labelling


def face_neighbours(mesh: trimesh.Trimesh) -> np.ndarray:
    """(F, 3) indices of the faces sharing an edge with each face, -1 padded (a non-manifold edge's extra
    neighbours are dropped)."""
    adjacency = np.asarray(mesh.face_adjacency)
    pairs = np.concatenate([adjacency, adjacency[:, ::-1]])
    pairs = pairs[np.argsort(pairs[:, 0], kind="stable")]
    counts = np.bincount(pairs[:, 0], minlength=len(mesh.faces))
    slot = np.arange(len(pairs)) - np.repeat(np.cumsum(counts) - counts, counts)
    keep = slot < 3
    neighbours = np.full((len(mesh.faces), 3), -1, np.int64)
    neighbours[pairs[keep, 0], slot[keep]] = pairs[keep, 1]
    return neighbours


def label_faces(views: FaceViews, neighbours: np.ndarray, smoothness: float, iterations: int) -> np.ndarray:
    """One photo index per face (-1 where no photo sees it): data cost + Potts smoothness, minimised by iterated
    conditional modes. Each round, every face that would lower its cost by changing does so unless a neighbour
    that also wants to change comes first in a fixed random order; so no two neighbours change together and the
    total cost falls every round (deterministic; at most ``iterations`` rounds)."""
    best = views.quality[:, :1]
    data = np.where(views.view >= 0, 1.0 - views.quality / np.where(best > 0, best, 1.0), np.inf)
    labels = views.view[:, 0].copy()
    priority = np.random.default_rng(0).permutation(len(labels))
    padded = np.where(neighbours >= 0, neighbours, len(labels))  # index of a sentinel that never wants to change
    for _ in range(iterations):
        around = np.where(neighbours >= 0, labels[neighbours], -1)  # (F, 3)
        disagree = (views.view[:, :, None] != around[:, None, :]) & (around[:, None, :] >= 0)
        choice = np.argmin(data + smoothness * disagree.sum(axis=2), axis=1)
        proposal = np.take_along_axis(views.view, choice[:, None], axis=1)[:, 0]
        wants = np.append(proposal != labels, False)
        rank = np.append(priority, len(labels))
        first = wants[:-1] & ~(wants[padded] & (rank[padded] < priority[:, None])).any(axis=1)
        if not first.any():
            break
        labels[first] = proposal[first]
    return labels


# ---------------------------------------------------------------- 3. charts and packing


def patches(mesh: trimesh.Trimesh, labels: np.ndarray) -> np.ndarray:
    """Patch id per face: connected components of edge-adjacent faces on the same photo (unseen faces: alone)."""
    adjacency = np.asarray(mesh.face_adjacency)
    a, b = adjacency[:, 0], adjacency[:, 1]
    same = (labels[a] == labels[b]) & (labels[a] >= 0)
    graph = sparse.coo_matrix((np.ones(np.count_nonzero(same)), (a[same], b[same])),
                              shape=(len(labels), len(labels)))
    return sparse.csgraph.connected_components(graph, directed=False)[1]


def split_by_patch(faces: np.ndarray, patch: np.ndarray, num_vertices: int):
    """Vertices duplicated per patch: (source vertex (M,), patch of each (M,), new faces (F, 3))."""
    key = patch[:, None].astype(np.int64) * num_vertices + faces
    unique, inverse = np.unique(key.ravel(), return_inverse=True)
    return unique % num_vertices, unique // num_vertices, inverse.reshape(-1, 3)


def in_plane_uv(triangles: np.ndarray) -> np.ndarray:
    """(F, 3, 2) coordinates (metres) of each triangle's corners in its own plane (corner 0 at the origin)."""
    edge1 = triangles[:, 1] - triangles[:, 0]
    edge2 = triangles[:, 2] - triangles[:, 0]
    axis_u = edge1 / np.maximum(np.linalg.norm(edge1, axis=1), 1e-12)[:, None]
    normal = np.cross(edge1, edge2)
    axis_v = np.cross(normal / np.maximum(np.linalg.norm(normal, axis=1), 1e-12)[:, None], axis_u)
    uv = np.zeros((len(triangles), 3, 2))
    for corner, edge in ((1, edge1), (2, edge2)):
        uv[:, corner] = np.column_stack([row_dots(edge, axis_u), row_dots(edge, axis_v)])
    return uv


def chart_uvs(mesh: trimesh.Trimesh, labels: np.ndarray, photos: list[Photo]):
    """Split vertices, faces and chart UVs before packing: (source vertex (M,), faces (F, 3), uv (M, 2)).

    A patch's UVs are its vertices' pixel positions in its photo (divided by the image's larger side); an unseen
    face's are its corners in its own plane, shifted so that no two such charts share a UV (xatlas welds vertices
    that share a position and a UV into one chart)."""
    vertices, faces = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)
    patch = patches(mesh, labels)
    source, vertex_patch, split_faces = split_by_patch(faces, patch, len(vertices))
    patch_label = np.full(patch.max() + 1, -1)
    patch_label[patch] = labels
    vertex_label = patch_label[vertex_patch]
    uv = np.zeros((len(source), 2))
    for k in np.unique(vertex_label[vertex_label >= 0]):
        own = vertex_label == k
        camera = photos[k].camera
        pixels, _ = project_world_points(camera, photos[k].T_world_cam, vertices[source[own]])
        uv[own] = pixels / max(camera.width, camera.height)
    unseen = np.flatnonzero(labels < 0)
    if len(unseen):
        flat = in_plane_uv(vertices[faces[unseen]])
        shift = np.column_stack([(unseen * 0.6180339887) % 1.0, (unseen * 0.4142135624) % 1.0]) * 10.0
        uv[split_faces[unseen].ravel()] = (flat + shift[:, None, :]).reshape(-1, 2)
    return source, split_faces, uv


def pack(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray, texels_per_m: float, max_texture_px: int,
         padding_px: int):
    """xatlas packing of the input charts: (vertex map (M',), faces (F, 3), uv (M', 2) in [0, 1] with v down as
    xatlas lays rows, width, height, texels per metre used). The density shrinks until the atlas fits."""
    while True:
        atlas = xatlas.Atlas()
        atlas.add_mesh(vertices.astype(np.float32), faces.astype(np.uint32), uvs=uv.astype(np.float32))
        charts = xatlas.ChartOptions()
        charts.use_input_mesh_uvs = True
        packing = xatlas.PackOptions()
        packing.padding = padding_px
        packing.texels_per_unit = texels_per_m
        packing.bilinear = True
        atlas.generate(charts, packing)
        if atlas.atlas_count == 1 and max(atlas.width, atlas.height) <= max_texture_px:
            vmapping, packed_faces, packed_uv = atlas[0]
            return vmapping, packed_faces.astype(np.int64), packed_uv, atlas.width, atlas.height, texels_per_m
        texels_per_m *= 0.95 * max_texture_px / max(atlas.width, atlas.height, max_texture_px + 1)


# ---------------------------------------------------------------- 4. exposure


def atlas_gains(views: FaceViews, centroids: np.ndarray, photos: list[Photo], linear: list[np.ndarray],
                options: AtlasOptions) -> np.ndarray:
    """Per-photo linear gains (geometric mean 1) from the candidates' luminance at up to ``gain_faces`` face
    centroids seen by at least two photos."""
    shared = np.flatnonzero((views.view >= 0).sum(axis=1) >= 2)
    sample = shared[np.linspace(0, len(shared) - 1, min(options.gain_faces, len(shared))).astype(np.int64)] \
        if len(shared) else shared
    log_luminance = np.full((len(photos), len(sample)), np.nan)
    for k, photo in enumerate(photos):
        column = np.flatnonzero((views.view[sample] == k).any(axis=1))
        if len(column):
            rgb = sample_photo(photo, linear[k], centroids[sample[column]])
            log_luminance[k, column] = np.log(np.maximum(rgb.mean(axis=1), 1e-4))
    return np.exp(solve_log_gains(log_luminance, options.min_overlap))


def held_out_gains(scene: Scene, mesh: trimesh.Trimesh, labels: np.ndarray, blend: FaceViews, photos: list[Photo],
                   linear: list[np.ndarray], gains: np.ndarray, held_out: list[Photo],
                   options: AtlasOptions) -> np.ndarray:
    """Exposure gains of photos left out of the texture (``held_out``), against the finished texture: the mean over
    up to ``gain_faces`` textured faces each sees (:func:`visible_faces`) of log(texture luminance) - log(its own
    luminance), the texture's luminance being the blend of the face's views at its centroid (:func:`blended_colour`).

    A held-out photo's exposure (auto-exposure, white balance) is a property of that photo that no twin can predict;
    one number per photo, measured the way the texture's own photos' gains are, so that ``compare`` can score the
    twin's colours at that photo's exposure. 1.0 for a photo that sees fewer than ``min_overlap`` textured faces.
    """
    centroids, normals = np.asarray(mesh.triangles_center), np.asarray(mesh.face_normals)
    result = np.ones(len(held_out))
    for index, photo in enumerate(held_out):
        faces, _ = visible_faces(scene, centroids, normals, photo, options.border_px)
        faces = faces[labels[faces] >= 0]
        if len(faces) < options.min_overlap:
            continue
        faces = faces[np.linspace(0, len(faces) - 1, min(options.gain_faces, len(faces))).astype(np.int64)]
        texture = blended_colour(blend, faces, centroids[faces], labels[faces], photos, linear, gains,
                                 options.blend_power).mean(axis=1)
        own_luminance = sample_photo(photo, linear_texture(photo.image), centroids[faces]).mean(axis=1)
        log_ratio = np.log(np.maximum(texture, 1e-4)) - np.log(np.maximum(own_luminance, 1e-4))
        result[index] = float(np.exp(log_ratio.mean()))
    return result


# ---------------------------------------------------------------- 5. texels


def sample_photo(photo: Photo, linear: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Linear RGB (N, 3) of the photo (its :func:`sim.render.texture.linear_texture`) at world points (bilinear); NaN
    where a point lies behind the photo or outside its image (a lookup there would wrap round to the image's other
    side: the colour of something else)."""
    pixels, depth = project_world_points(photo.camera, photo.T_world_cam, points)
    cam = photo.camera
    uv = np.column_stack([(pixels[:, 0] + 0.5) / cam.width, 1.0 - (pixels[:, 1] + 0.5) / cam.height])
    rgb = sample_linear(linear, np.nan_to_num(uv).astype(np.float32))
    rgb[~in_image(cam, pixels, depth)] = np.nan
    return rgb


#: Blend weights below this share of the best are left out.
MIN_BLEND_WEIGHT = 0.02


def blended_colour(views: FaceViews, face: np.ndarray, points: np.ndarray, label: np.ndarray, photos: list[Photo],
                   linear: list[np.ndarray], gains: np.ndarray, blend_power: float) -> np.ndarray:
    """Linear RGB (N, 3) at ``points`` on ``face``: the gain-balanced mean of the face's candidate photos weighted by
    (quality / best quality)^``blend_power`` (inf: the face's ``label`` photo alone), over the photos whose image
    holds the point; NaN where none does. A face's own photo need not see all of it (a long sliver of a flat roof or
    a pond, chosen by its centroid)."""
    if not np.isfinite(blend_power):
        view = label[:, None]
        weight = np.ones((len(face), 1))
    else:
        view, quality = views.view[face], views.quality[face]
        best = np.maximum(quality.max(axis=1, keepdims=True), 1e-30)
        weight = np.where(view >= 0, (quality / best) ** blend_power, 0.0)
        weight[weight < MIN_BLEND_WEIGHT] = 0.0
    rows, slots = np.nonzero(weight > 0)
    photo = view[rows, slots]
    weighted = np.empty((len(rows), 3))
    for k in np.unique(photo):
        own = photo == k
        weighted[own] = gains[k] * sample_photo(photos[k], linear[k], points[rows[own]])
    sample_weight = np.where(np.isfinite(weighted[:, 0]), weight[rows, slots], 0.0)
    weighted = np.nan_to_num(weighted) * sample_weight[:, None]
    total = np.column_stack([np.bincount(rows, weights=weighted[:, c], minlength=len(face)) for c in range(3)])
    weight_sum = np.bincount(rows, weights=sample_weight, minlength=len(face))
    return np.where(weight_sum[:, None] > 0, total / np.maximum(weight_sum, 1e-30)[:, None], np.nan)


def rasterise_faces(uv_px: np.ndarray, faces: np.ndarray, width: int, height: int, padding_px: int) -> np.ndarray:
    """(height, width) int32 face index of every texel (-1: none); texels of the gutter within ``padding_px`` take
    the nearest face's index. ``uv_px`` are texel coordinates (pixel centres at integers)."""
    ids = np.full((height, width), -1, np.int32)
    corners = np.round(uv_px[faces] * (1 << RASTER_SHIFT)).astype(np.int32)
    for index, triangle in enumerate(corners):
        cv2.fillConvexPoly(ids, triangle, index, lineType=cv2.LINE_8, shift=RASTER_SHIFT)
    empty = ids < 0
    if empty.any() and padding_px > 0:
        distance, nearest = ndimage.distance_transform_edt(empty, return_indices=True)
        gutter = empty & (distance <= padding_px)
        ids[gutter] = ids[nearest[0][gutter], nearest[1][gutter]]
    return ids


def dot2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of two (N, 2) arrays."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]


def texel_weights(uv_px: np.ndarray, texel_xy: np.ndarray) -> np.ndarray:
    """Barycentric weights (N, 3) of texel centres ``texel_xy`` (N, 2) in triangles given by their texel corners
    ``uv_px`` (N, 3, 2), clamped to the triangle (a gutter texel takes the nearest point of its face)."""
    v0, v1 = uv_px[:, 1] - uv_px[:, 0], uv_px[:, 2] - uv_px[:, 0]
    v2 = texel_xy - uv_px[:, 0]
    d00, d01, d11 = dot2(v0, v0), dot2(v0, v1), dot2(v1, v1)
    d20, d21 = dot2(v2, v0), dot2(v2, v1)
    denominator = d00 * d11 - d01 * d01
    degenerate = np.abs(denominator) < 1e-12
    denominator[degenerate] = 1.0
    b1 = np.where(degenerate, 1.0 / 3.0, (d11 * d20 - d01 * d21) / denominator)
    b2 = np.where(degenerate, 1.0 / 3.0, (d00 * d21 - d01 * d20) / denominator)
    weights = np.clip(np.column_stack([1.0 - b1 - b2, b1, b2]), 0.0, None)
    return weights / np.maximum(weights.sum(axis=1), 1e-12)[:, None]


def texel_points(chunk: np.ndarray, flat_ids: np.ndarray, uv_px: np.ndarray, faces: np.ndarray,
                 vertices: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For texels ``chunk`` (flat indices into an atlas ``width`` wide whose texel faces are ``flat_ids``): their face
    (N,), barycentric weights in it (N, 3) (:func:`texel_weights`) and 3-D points (N, 3), ENU metres."""
    face = flat_ids[chunk]
    rows, cols = np.divmod(chunk, width)
    weights = texel_weights(uv_px[faces[face]], np.column_stack([cols, rows]).astype(float))
    return face, weights, np.einsum("nk,nkj->nj", weights, vertices[faces[face]])


def paint(ids: np.ndarray, uv_px: np.ndarray, faces: np.ndarray, vertices: np.ndarray, labels: np.ndarray,
          photos: list[Photo], linear: list[np.ndarray], gains: np.ndarray, blend: FaceViews, blend_power: float,
          capture: CaptureSetup | None = None
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, Delighting | None]:
    """The atlas image (H, W, 3) uint8 sRGB: every texel of a seen face that a photo holds the blend of the face's
    ``blend`` views (:func:`blended_colour`); the rest take the nearest painted texel (grey if none). Also which faces
    photos hold most of (:func:`photographed_faces`). With ``capture`` (the capture suns): the albedo instead, the
    capture light (H, W, 3) float32 it was divided by, and what was done (:mod:`recon.appearance.delight`; its sun/sky
    ratio fitted on each face's own photo, whose shadow edges no blend has softened)."""
    height, width = ids.shape
    colour = np.zeros((height * width, 3), np.float32)
    flat = ids.ravel()
    texels = np.flatnonzero((flat >= 0) & (labels[np.maximum(flat, 0)] >= 0))
    parts = []
    for start in range(0, len(texels), TEXEL_CHUNK):
        chunk = texels[start:start + TEXEL_CHUNK]
        face, weights, points = texel_points(chunk, flat, uv_px, faces, vertices, width)
        colour[chunk] = blended_colour(blend, face, points, labels[face], photos, linear, gains, blend_power)
        if capture is not None:
            parts.append(capture.texel_light(face, weights, points, labels[face], photos))
    photographed = np.isfinite(colour[texels, 0])
    face_seen = photographed_faces(flat[texels], photographed, labels)
    colour[texels[~photographed]] = 0.0
    texels = texels[photographed]

    def own_photo_colour(wanted: np.ndarray) -> np.ndarray:
        """The face's own photo's colour where it holds the texel, else the blend's."""
        own = np.empty((len(wanted), 3))
        for start in range(0, len(wanted), TEXEL_CHUNK):
            face, _, points = texel_points(wanted[start:start + TEXEL_CHUNK], flat, uv_px, faces, vertices, width)
            own[start:start + TEXEL_CHUNK] = blended_colour(blend, face, points, labels[face], photos, linear, gains,
                                                            np.inf)
        return np.where(np.isfinite(own), own, colour[wanted])

    light, result = None, None
    if capture is not None and len(texels):
        light, result = delight_atlas(colour, texels, TexelLight.joined(parts).subset(photographed),
                                      capture.chart[np.maximum(flat, 0)], ids.shape, capture.sun_sky_ratio,
                                      own_photo_colour)
    image = to_srgb8(colour).reshape(height, width, 3)
    if len(texels) == 0:
        return np.full_like(image, 128), face_seen, None, result
    nearest = _nearest_painted(texels, ids)
    return image[nearest], face_seen, None if light is None else light.reshape(height, width, 3)[nearest], result


def photographed_faces(texel_face: np.ndarray, photographed: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """(F,) True for the faces a photo colours (``labels`` >= 0) whose texels (``texel_face``: the face of each texel,
    ``photographed``: whether a photo held it) a photo held at least half of; the rest of their colour is copied from
    the nearest painted texel. A face with no texel of its own counts as its label says."""
    texels = np.bincount(texel_face, minlength=len(labels))
    held = np.bincount(texel_face, weights=photographed, minlength=len(labels))
    return (labels >= 0) & ((texels == 0) | (2 * held >= texels))


def _nearest_painted(texels: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For every texel, the (row, column) of the nearest painted one (``texels``: flat indices of the painted)."""
    unpainted = np.ones(ids.size, bool)
    unpainted[texels] = False
    return tuple(ndimage.distance_transform_edt(unpainted.reshape(ids.shape), return_distances=False,
                                                return_indices=True))


# ---------------------------------------------------------------- the whole stage


def texture_atlas(mesh: trimesh.Trimesh, photos: list[Photo], options: AtlasOptions = AtlasOptions(),
                  progress=lambda it: it, log=lambda message: None, held_out: list[Photo] = (),
                  sun_enu: np.ndarray | None = None, sun_sky_ratio: tuple[float, float, float] | None = None) -> Atlas:
    """The textured atlas of an ENU ``mesh`` from undistorted ``photos`` (see the module docstring); the gains also
    name the ``held_out`` photos, which colour nothing (:func:`held_out_gains`). With ``sun_enu`` (K, 3), each photo's
    capture sun (unit ENU, towards the sun), the atlas holds the albedo and the capture light
    (:mod:`recon.appearance.delight`), whose sun/sky ratio per channel is ``sun_sky_ratio`` where it was measured,
    else fitted from the atlas's shadow edges."""
    if not photos:
        raise ValueError("texturing needs at least one photo")
    scene = scene_from_mesh(mesh)
    views = face_candidates(scene, mesh, photos, options, progress)
    labels = label_faces(views, face_neighbours(mesh), options.smoothness, options.iterations)
    blend = blend_views(views, labels, corners_seen(scene, mesh, photos, views))
    linear = [linear_texture(photo.image) for photo in photos]
    centroids = np.asarray(mesh.triangles_center)
    gains = (atlas_gains(views, centroids, photos, linear, options) if options.balance_exposure
             else np.ones(len(photos)))
    source, split_faces, uv = chart_uvs(mesh, labels, photos)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    texel_m = options.texel_m or photo_pixel_m(views)
    vmapping, faces, packed_uv, width, height, texels_per_m = pack(
        vertices[source], split_faces, uv, 1.0 / texel_m, options.max_texture_px, options.padding_px)
    packed_vertices = stored_positions(vertices[source[vmapping]])  # the GLB's: the delight's bake is the scene's
    uv_px = packed_uv * np.array([width, height]) - 0.5
    ids = rasterise_faces(uv_px, faces, width, height, options.padding_px)
    capture = None if sun_enu is None else CaptureSetup.of(packed_vertices, faces, sun_enu, patches(mesh, labels),
                                                           sun_sky_ratio)
    image, face_seen, capture_light, delighting = paint(ids, uv_px, faces, packed_vertices, labels, photos, linear,
                                                        gains, blend, options.blend_power, capture)
    if delighting is not None:
        source = "as measured" if sun_sky_ratio is not None else f"from {delighting.blocks} shadow-edge blocks"
        log(f"capture light: sun/sky ratio {np.round(delighting.ratio, 2).tolist()} {source}; {delighting.relit} "
            f"texels predicted in shadow were lit")
    area = np.asarray(mesh.area_faces)
    coverage = float(area[labels >= 0].sum() / max(area.sum(), 1e-12))
    log(f"{len(faces)} faces on {len(np.unique(labels[labels >= 0]))} photos in {patches(mesh, labels).max() + 1} "
        f"patches")
    held_gains = held_out_gains(scene, mesh, labels, blend, photos, linear, gains, list(held_out), options)
    named_gains = {photo.name: float(g) for photo, g in zip([*photos, *held_out], [*gains, *held_gains])}
    return Atlas(packed_vertices, faces, np.column_stack([packed_uv[:, 0], 1.0 - packed_uv[:, 1]]), image, labels,
                 face_seen, named_gains, coverage,
                 1.0 / texels_per_m, capture_light if delighting is not None and delighting.applied else None,
                 delighting, None if capture is None else capture.scene_bake())
