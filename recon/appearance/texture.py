"""Texture a 2.5-D surface from the photos: a true orthophoto in the scene's ENU x/y plane.

Texels are the cells of a regular grid in ENU east/north (row 0 = north edge), ``texel_m`` metres each (default:
one ground pixel of the photos, i.e. median viewing distance / focal length). Each texel's 3-D point and normal
come from a vertical ray onto the mesh (sim's embree scene built from the mesh in memory). For every photo
(undistorted pinhole camera, ``T_world_cam`` in the same ENU frame):

1. project the texel points (``sim.render.camera.project_world_points``); keep those in front, inside the image and
   facing the camera;
2. **visibility**: an occlusion ray (``sim.render.raycast.occluded``) from the camera centre towards each point; the
   texel is seen when nothing is hit before it (up to ``max(0.05 m, 0.2 %)`` of the camera distance short of it);
3. sample the photo bilinearly in linear light;
4. weight = border feather (0 at the image edge, 1 beyond ``feather_px``) x quality**``view_power`` with
   quality = cos(viewing angle) x (reference distance / distance): the best view dominates and neighbouring
   views blend smoothly across seams instead of switching.

**Exposure balancing**: per-photo gains ``g`` (linear light) with ``g_i * I_i = g_j * I_j`` on texels both see,
solved by weighted least squares on log luminance over a coarse texel grid (pair means, weight = overlap count;
geometric mean of the gains 1). Colours are ``sum(w g I) / sum(w)``; texels no photo sees take the nearest seen
texel's colour.
"""

from __future__ import annotations

import io
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import trimesh
from PIL import Image
from scipy import ndimage

from flightplan.geodesy import LocalFrame
from recon.sfm.cameras import camera_from_colmap, camera_poses
from recon.surface.mesh import scene_from_mesh
from sim.render.camera import PinholeCamera, project_world_points
from sim.render.raycast import default_workers, from_above, intersect, occluded
from sim.render.scene import Scene
from sim.render.texture import sample_bilinear
from sim.render.color import to_srgb8
from sim.render.glb import encode_textured_glb

JPEG_QUALITY = 95
#: Texels per side of the culling tiles.
TILE_TEXELS = 64


@dataclass(frozen=True)
class Photo:
    """One photo for texturing: ``image`` (H, W, 3) uint8 sRGB, undistorted; pinhole ``camera`` without
    distortion; ``T_world_cam`` 4x4 camera-to-world in the mesh's ENU frame (OpenCV axes)."""

    name: str
    image: np.ndarray
    camera: PinholeCamera
    T_world_cam: np.ndarray


@dataclass(frozen=True)
class TextureOptions:
    """``texel_m`` None = one ground pixel of the photos (capped so the texture is at most ``max_texture_px``
    on a side); ``view_power`` sharpens best-view selection; ``feather_px`` border blend width;
    ``gain_stride`` texel step of the exposure-balancing grid; ``min_overlap`` texels for a photo pair to count."""

    texel_m: float | None = None
    max_texture_px: int = 4096
    view_power: float = 8.0
    feather_px: float = 16.0
    balance_exposure: bool = True
    gain_stride: int = 4
    min_overlap: int = 30

    def __post_init__(self) -> None:
        if self.texel_m is not None and not (np.isfinite(self.texel_m) and self.texel_m > 0):
            raise ValueError(f"texel size must be a positive number of metres, got {self.texel_m}")


@dataclass(frozen=True)
class Texels:
    """The texel grid: ``(rows, cols)``, west/south edges ``xmin``/``ybottom`` (ENU m), ``texel_m``; per texel
    (flattened, row-major) surface ``points`` (N, 3) and unit ``normals`` (N, 3), NaN / 0 off the mesh."""

    rows: int
    cols: int
    xmin: float
    ybottom: float
    texel_m: float
    points: np.ndarray
    normals: np.ndarray

    @property
    def on_mesh(self) -> np.ndarray:
        return np.isfinite(self.points[:, 2])

    def uv(self, xy: np.ndarray) -> np.ndarray:
        """Texture coordinates (v up, OBJ/trimesh convention) of ENU x/y positions."""
        return np.column_stack([(xy[:, 0] - self.xmin) / (self.cols * self.texel_m),
                                (xy[:, 1] - self.ybottom) / (self.rows * self.texel_m)])


@dataclass(frozen=True)
class Tiles:
    """On-mesh texels in square tiles, for culling those a photo cannot see: ``order`` flat texel indices sorted
    by tile, ``start`` (tiles + 1) offsets into it, tile ``centre`` (T, 3) ENU and bounding ``radius`` (T,) m."""

    order: np.ndarray
    start: np.ndarray
    centre: np.ndarray
    radius: np.ndarray

    @classmethod
    def of(cls, texels: Texels, size: int = TILE_TEXELS) -> "Tiles":
        flat = np.flatnonzero(texels.on_mesh)
        rows, cols = np.divmod(flat, texels.cols)
        tile = (rows // size) * (-(-texels.cols // size)) + cols // size
        sort = np.argsort(tile, kind="stable")
        order = flat[sort]
        start = np.append(np.unique(tile[sort], return_index=True)[1], len(order))
        counts = np.diff(start)
        points = texels.points[order]
        centre = np.add.reduceat(points, start[:-1], axis=0) / counts[:, None]
        spread = np.linalg.norm(points - np.repeat(centre, counts, axis=0), axis=1)
        return cls(order, start, centre, np.maximum.reduceat(spread, start[:-1]))

    def in_view(self, photo: Photo) -> np.ndarray:
        """Flat indices of the texels in tiles whose bounding sphere may appear in the photo (generously)."""
        T, cam = np.asarray(photo.T_world_cam, dtype=np.float64), photo.camera
        local = (self.centre - T[:3, 3]) @ T[:3, :3]
        z = local[:, 2]
        near = z - self.radius
        depth = np.maximum(near, 1e-6)
        px = cam.fx * local[:, 0] / depth + cam.cx
        py = cam.fy * local[:, 1] / depth + cam.cy
        margin = 2.0 * cam.fx * self.radius / depth * (1.0 + np.abs(local[:, 0] / depth) + np.abs(local[:, 1] / depth))
        projected_inside = ((px > -margin) & (px < cam.width - 1 + margin)
                            & (py > -margin) & (py < cam.height - 1 + margin))
        keep = np.flatnonzero((z + self.radius > 0) & ((near <= 0) | projected_inside))
        if len(keep) == 0:
            return np.zeros(0, np.int64)
        return np.concatenate([self.order[self.start[k]:self.start[k + 1]] for k in keep])


@dataclass(frozen=True)
class Orthophoto:
    """The texture (rows, cols, 3) uint8 sRGB with its grid, per-photo ``gains``, the ``coverage`` fraction of
    on-mesh texels seen by at least one photo and which texels were (``covered``, (rows, cols) bool; the others hold
    the nearest covered texel's colour)."""

    image: np.ndarray
    texels: Texels
    gains: dict[str, float]
    coverage: float
    covered: np.ndarray

    def face_seen(self, mesh: trimesh.Trimesh) -> np.ndarray:
        """(F,) bool per face of ``mesh`` (ENU metres): a photo saw the texel under the face's centroid."""
        uv = self.texels.uv(np.asarray(mesh.triangles_center)[:, :2])
        col = np.clip((uv[:, 0] * self.texels.cols).astype(np.int64), 0, self.texels.cols - 1)
        row = np.clip(((1.0 - uv[:, 1]) * self.texels.rows).astype(np.int64), 0, self.texels.rows - 1)
        return self.covered[row, col]


@dataclass(frozen=True)
class Samples:
    """What one photo sees: flat texel ``index``, linear ``rgb`` (K, 3) float32 and blend ``weight`` (K,)."""

    index: np.ndarray
    rgb: np.ndarray
    weight: np.ndarray


def ground_sample_distance(scene: Scene, photos: list[Photo]) -> float:
    """Median over photos of (distance to the surface at the image centre / focal length), metres per pixel."""
    gsd = []
    for photo in photos:
        T = np.asarray(photo.T_world_cam, dtype=np.float64)
        hits = intersect(scene, T[None, :3, 3], T[None, :3, 2])
        if hits.hit[0]:
            gsd.append(float(hits.t[0]) / photo.camera.fx)
    if not gsd:
        raise ValueError("no photo looks at the mesh (no image-centre ray hits it): wrong poses or frame?")
    return float(np.median(gsd))


def texel_grid(scene: Scene, texel_m: float, max_texture_px: int) -> Texels:
    """Texels over the mesh's x/y bounds, with points and normals from vertical rays (topmost surface)."""
    (xmin, ymin, _), (xmax, ymax, _) = scene.bounds
    texel_m = max(texel_m, (xmax - xmin) / max_texture_px, (ymax - ymin) / max_texture_px)
    cols, rows = max(1, int(np.ceil((xmax - xmin) / texel_m))), max(1, int(np.ceil((ymax - ymin) / texel_m)))
    x = xmin + (np.arange(cols) + 0.5) * texel_m
    y = ymax - (np.arange(rows) + 0.5) * texel_m
    gx, gy = np.meshgrid(x, y)
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    heights, hits = from_above(scene, xy)
    return Texels(rows, cols, float(xmin), float(ymax - rows * texel_m), float(texel_m), np.column_stack([xy, heights]),
                  hits.normal.astype(np.float64))


def photo_samples(scene: Scene, photo: Photo, texels: Texels, options: TextureOptions, subset: np.ndarray,
                  reference_distance: float) -> Samples:
    """Visible texels among ``subset`` (flat indices) for one photo, their linear colours and blend weights."""
    centre = np.asarray(photo.T_world_cam, dtype=np.float64)[:3, 3]
    cam = photo.camera
    points = texels.points[subset]
    pixels, _ = project_world_points(cam, photo.T_world_cam, points)  # NaN behind the camera
    px, py = pixels[:, 0], pixels[:, 1]
    inside = (px >= 0) & (px <= cam.width - 1) & (py >= 0) & (py <= cam.height - 1)
    to_camera = centre - points[inside]
    distance = np.linalg.norm(to_camera, axis=1)
    direction = to_camera / distance[:, None]
    cosine = np.einsum("ij,ij->i", direction, texels.normals[subset[inside]])
    facing = cosine > 0.05
    keep = np.flatnonzero(inside)[facing]
    distance, direction, cosine = distance[facing], direction[facing], cosine[facing]
    if len(keep) == 0:
        return Samples(np.zeros(0, np.int64), np.zeros((0, 3), np.float32), np.zeros(0))
    tolerance = np.maximum(0.05, 2e-3 * distance)  # the texel's own surface must not hide it
    seen = ~occluded(scene, centre[None], -direction, distance - tolerance)
    keep, distance, cosine = keep[seen], distance[seen], cosine[seen]
    u, v = px[keep], py[keep]
    uv = np.column_stack([(u + 0.5) / cam.width, 1.0 - (v + 0.5) / cam.height]).astype(np.float32)
    rgb = sample_bilinear(photo.image, uv)
    border = np.minimum.reduce([u, cam.width - 1 - u, v, cam.height - 1 - v])
    feather = np.clip(border / options.feather_px, 0.0, 1.0)
    quality = np.clip(cosine * reference_distance / distance, 0.0, None)
    weight = feather * quality ** options.view_power
    return Samples(subset[keep], rgb, weight)


def solve_log_gains(log_luminance: np.ndarray, min_overlap: int) -> np.ndarray:
    """Per-photo log gains ``a`` (mean 0) with ``a_i + L_i ~ a_j + L_j`` on shared samples.

    ``log_luminance`` is (photos, samples) with NaN where a photo does not see a sample. Each photo pair sharing
    at least ``min_overlap`` samples gives one equation ``a_i - a_j = -mean(L_i - L_j)``, weighted by the square
    root of the overlap; a tiny ridge keeps photos without overlap at 0.
    """
    seen = np.isfinite(log_luminance).astype(np.float64)
    values = np.where(seen > 0, log_luminance, 0.0)
    overlap = seen @ seen.T
    sums = values @ seen.T  # sums[i, j] = sum over shared samples of L_i
    i, j = np.nonzero(np.triu(overlap >= min_overlap, k=1))
    n = len(log_luminance)
    rows = np.zeros((len(i) + n, n))
    weight = np.sqrt(overlap[i, j])
    rows[np.arange(len(i)), i] = weight
    rows[np.arange(len(i)), j] = -weight
    target = np.zeros(len(i) + n)
    target[:len(i)] = -(sums[i, j] - sums[j, i]) / overlap[i, j] * weight
    rows[len(i):] = np.eye(n) * 1e-3 * np.sqrt(max(overlap.max(), 1.0))
    gains = np.linalg.lstsq(rows, target, rcond=None)[0]
    return gains - gains.mean()


def exposure_gains(scene: Scene, photos: list[Photo], texels: Texels, tiles: Tiles, options: TextureOptions,
                   reference_distance: float) -> np.ndarray:
    """Per-photo linear gains (geometric mean 1) from the coarse texel grid (every ``gain_stride``-th texel)."""
    grid = np.arange(texels.rows * texels.cols).reshape(texels.rows, texels.cols)
    coarse = grid[::options.gain_stride, ::options.gain_stride].ravel()
    coarse = coarse[texels.on_mesh[coarse]]
    position = np.full(texels.rows * texels.cols, -1)
    position[coarse] = np.arange(len(coarse))
    log_luminance = np.full((len(photos), len(coarse)), np.nan)
    for k, photo in enumerate(photos):
        candidates = tiles.in_view(photo)
        candidates = candidates[position[candidates] >= 0]
        samples = photo_samples(scene, photo, texels, options, candidates, reference_distance)
        useful = samples.weight > 0
        luminance = samples.rgb[useful].mean(axis=1)
        log_luminance[k, position[samples.index[useful]]] = np.log(np.maximum(luminance, 1e-4))
    return np.exp(solve_log_gains(log_luminance, options.min_overlap))


def orthophoto(mesh: trimesh.Trimesh, photos: list[Photo], options: TextureOptions = TextureOptions(),
               progress=lambda iterable: iterable) -> Orthophoto:
    """The orthophoto texture of an ENU ``mesh`` from ``photos`` (see the module docstring)."""
    if not photos:
        raise ValueError("texturing needs at least one photo")
    scene = scene_from_mesh(mesh)
    gsd = ground_sample_distance(scene, photos)
    texels = texel_grid(scene, options.texel_m or gsd, options.max_texture_px)
    reference_distance = gsd * float(np.median([p.camera.fx for p in photos]))
    tiles = Tiles.of(texels)
    gains = (exposure_gains(scene, photos, texels, tiles, options, reference_distance) if options.balance_exposure
             else np.ones(len(photos)))
    on_mesh = np.flatnonzero(texels.on_mesh)
    weight_sum = np.zeros(texels.rows * texels.cols)
    colour_sum = np.zeros((texels.rows * texels.cols, 3))
    for photo, gain in zip(progress(photos), gains):
        samples = photo_samples(scene, photo, texels, options, tiles.in_view(photo), reference_distance)
        weight_sum[samples.index] += samples.weight
        colour_sum[samples.index] += samples.weight[:, None] * gain * samples.rgb
    covered = weight_sum > 0
    colour = colour_sum / np.where(covered, weight_sum, 1.0)[:, None]
    image = to_srgb8(colour).reshape(texels.rows, texels.cols, 3)
    image = fill_uncovered(image, covered.reshape(texels.rows, texels.cols))
    coverage = float(np.count_nonzero(covered[on_mesh])) / max(len(on_mesh), 1)
    return Orthophoto(image, texels, {p.name: float(g) for p, g in zip(photos, gains)}, coverage,
                      covered.reshape(texels.rows, texels.cols))


def fill_uncovered(image: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """Texels no photo saw take the colour of the nearest seen texel (grey if none was seen)."""
    if not covered.any():
        return np.full_like(image, 128)
    nearest = ndimage.distance_transform_edt(~covered, return_distances=False, return_indices=True)
    return image[tuple(nearest)]


def textured_glb(mesh: trimesh.Trimesh, ortho: Orthophoto, origin: LocalFrame, generator: str = "recon.texture") -> bytes:
    """Binary glTF of ``mesh`` (ENU metres at ``origin``; stored +Y up and georeferenced by sim/render/glb.py) with
    UVs into the orthophoto, embedded as JPEG."""
    buffer = io.BytesIO()
    Image.fromarray(ortho.image).save(buffer, format="JPEG", quality=JPEG_QUALITY, subsampling=0)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    return encode_textured_glb(vertices, np.asarray(mesh.faces), ortho.texels.uv(vertices[:, :2]),
                               buffer.getvalue(), generator, origin)


def load_photos(model, image_dir, read_rgb) -> list[Photo]:
    """Photos of every registered image of an undistorted pycolmap model; ``read_rgb(path)`` decodes one."""
    registered = sorted((img for img in model.images.values() if img.has_pose), key=lambda img: img.name)
    with ThreadPoolExecutor(default_workers()) as pool:
        images = list(pool.map(lambda img: read_rgb(image_dir / img.name), registered))
    poses = camera_poses(model)
    return [Photo(img.name, rgb, camera_from_colmap(img.camera), poses[img.name])
            for img, rgb in zip(registered, images)]
