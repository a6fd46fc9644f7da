"""Build the built-in demo world as an ordinary scene folder, and keep one built copy per variant in a cache.

The world is generated around ``flightplan.demo_location.DEMO_ORIGIN``: ENU metres, z up, the ground at z = 0
under the origin. The folder holds ``world.glb`` (binary glTF, +Y up as the spec says: ENU metres stored as
``x = E, y = U, z = -N`` with the georeference in ``scenes[0].extras``, sim/render/glb.py; one JPEG texture atlas
with UVs embedded), ``scene.json`` (``aerostereo-scene/1``, see docs/interfaces.md) and ``labels.npz``, every face's
exact class and object (sim/render/labels.py; how each is decided: sim/worlds/ground_cover.py, docs/demo-world.md).
"""

from __future__ import annotations

import io
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from cliutil.atomic import write_bytes_atomic, write_text_atomic
from flightplan.demo_location import DEMO_ORIGIN
from sim.render.classes import class_table
from sim.render.labels import FORMAT as LABELS_FORMAT
from sim.render.labels import LABELS_FILE, SceneLabels, concatenate_labels, write_labels
from sim.render.sky_file import FORMAT as SKY_FORMAT, SKY_FILE, mesh_sha256
from sim.worlds.atlas import allocate_facades
from sim.worlds.facades import paint_facades
from sim.worlds.built import OBJECT_KINDS, built_part, clear_sites, paint_built, place_built
from sim.worlds.geometry import Part, concatenate, world_part
from sim.render.glb import encode_textured_glb
from sim.worlds.layout import VARIANTS, Layout, WorldSpec, generate_layout
from sim.worlds.orthophoto import paint_orthophoto
from sim.worlds.foliage import paint_vegetation_patches
from sim.worlds.vegetation import vegetation_parts, vegetation_truth

GENERATOR_VERSION = 10
"""Bump whenever the bytes written for a given (variant, seed) change, so stale caches are not reused. 8: the folder
gained labels.npz and scene.json its "labels" and "classes" (world.glb unchanged). 9 (two branches, two worlds): trees
with trunks, branches and porous crowns, conifers in whorls, a forest stand and hedges (sim/worlds/vegetation.py) and
their truth in scene.json's "vegetation"; or chimneys, dormers, lamp posts, a power line, fences, parked cars and a
pond (sim/worlds/built.py), their classes and scene.json's "objects". 10: both in one world."""
MESH_NAME = "world.glb"
SCENE_JSON = "scene.json"
JPEG_QUALITY = 95
LABELS_METHOD = ("exact: the generator's own parts (walls, roofs, trees with their trunks and branches, hedges: one "
                 "object per building, per tree and per hedge; chimneys, poles, wires, fences, cars and the pond: one "
                 "object each, dormers their building's); "
                 "terrain faces by the orthophoto's ground cover at their centroid (road, yard or village lawn: "
                 "ground, else field)")


def _spec(variant: str) -> WorldSpec:
    if variant not in VARIANTS:
        raise ValueError(f"unknown demo world variant {variant!r}; expected one of {sorted(VARIANTS)}")
    return VARIANTS[variant]


def _generators(seed: int, variant: str) -> tuple[np.random.Generator, ...]:
    """Independent generators for layout, painting and mesh details, all fixed by (seed, variant)."""
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    entropy = [int(seed), list(VARIANTS).index(variant)]  # declaration order: a new variant changes no other
    # A spawned stream depends on its index only: adding the fourth (built details) changed none of the first three.
    return tuple(np.random.default_rng(s) for s in np.random.SeedSequence(entropy).spawn(4))


def generate_world(variant: str = "default",
                   seed: int = 0) -> tuple[Layout, Part, np.ndarray, SceneLabels, list[dict]]:
    """The layout (its terrain with the pond cut in, without the trees in the pond's or the wires' way), the textured
    mesh (ENU metres), the (texture_px, texture_px, 3) uint8 RGB atlas, the labels of the mesh's faces and the truth
    of the built objects (sim/worlds/built.py) of a world."""
    spec = _spec(variant)
    layout_rng, paint_rng, mesh_rng, built_rng = _generators(seed, variant)
    layout, pond, power_line = clear_sites(built_rng, generate_layout(spec, layout_rng))
    facades = allocate_facades(layout.buildings, spec)
    atlas = np.zeros((spec.texture_px, spec.texture_px, 3), np.float32)
    atlas[: spec.ortho_rows], cover = paint_orthophoto(paint_rng, layout)
    built = place_built(built_rng, layout, pond, power_line, cover.yards)
    paint_built(built_rng, atlas[: spec.ortho_rows], built, spec)
    paint_facades(paint_rng, facades, layout.buildings, atlas)
    paint_vegetation_patches(paint_rng, atlas, spec)
    mesh, labels = world_part(layout, facades, cover, vegetation_parts(layout, mesh_rng))
    first_object = len(layout.buildings) + len(layout.trees) + len(layout.hedges) + 1
    details, detail_labels, objects = built_part(built, layout, facades, first_object)
    return (layout, concatenate([mesh, details]), np.clip(atlas, 0, 255).astype(np.uint8),
            concatenate_labels([labels, detail_labels]), objects)


def encode_glb(mesh: Part, atlas: np.ndarray) -> bytes:
    """Binary glTF of the ENU mesh (stored +Y up, georeferenced at the demo origin) with the atlas as one
    embedded JPEG."""
    buffer = io.BytesIO()
    Image.fromarray(atlas).save(buffer, format="JPEG", quality=JPEG_QUALITY, subsampling=0)
    return encode_textured_glb(mesh.vertices, mesh.faces, mesh.uv, buffer.getvalue(), generator="sim.worlds.demo",
                               origin=DEMO_ORIGIN)


def stored_mesh_sha256(mesh: Part) -> str:
    """:func:`~sim.render.sky_file.mesh_sha256` of ``mesh`` as a scene reads it back from its ``world.glb``: the GLB
    holds float32 positions, which turn back into the very same ENU values (sim/render/glb.py), and every face in
    order."""
    return mesh_sha256(mesh.vertices.astype(np.float32).astype(np.float64), mesh.faces)


def ground_height_range(layout: Layout, mesh: Part) -> tuple[float, float]:
    """Min and max ENU z (metres) of the ground: the terrain vertices, which come first in the mesh."""
    spec = layout.spec
    half_x, half_y = spec.half_extent_m
    xy = mesh.vertices[:, :2]
    on_ground = np.isclose(mesh.vertices[:, 2], layout.terrain.height(xy[:, 0], xy[:, 1]), atol=1e-9)
    on_ground &= (np.abs(xy[:, 0]) <= half_x + 1e-9) & (np.abs(xy[:, 1]) <= half_y + 1e-9)
    z = mesh.vertices[on_ground, 2]
    return float(z.min()), float(z.max())


def _rounded_outwards(low_high: tuple[float, float], step: float = 1e-4) -> list[float]:
    """``[low, high]`` rounded to ``step`` so that the rounded range still contains the exact one."""
    return [round(float(np.floor(low_high[0] / step) * step), 9), round(float(np.ceil(low_high[1] / step) * step), 9)]


def scene_description(layout: Layout, mesh: Part, labels: SceneLabels, variant: str, seed: int,
                      objects: list[dict]) -> dict:
    """The ``scene.json`` content of a built world."""
    half_x, half_y = layout.spec.half_extent_m
    return {
        "format": "aerostereo-scene/1",
        "mesh": MESH_NAME,
        "origin": DEMO_ORIGIN.to_dict(),
        "units": "m",
        "up_axis": "y",
        "frame": "enu",
        "vertex_offset_m": [0.0, 0.0, 0.0],
        "ground_height_range_m": _rounded_outwards(ground_height_range(layout, mesh)),
        "valid_area_m": {"xmin": -half_x, "xmax": half_x, "ymin": -half_y, "ymax": half_y},
        "provenance": {
            "generator": "sim.worlds.demo",
            "generator_version": GENERATOR_VERSION,
            "variant": variant,
            "seed": int(seed),
            "triangles": int(len(mesh.faces)),
            "texture_px": int(layout.spec.texture_px),
            "buildings": len(layout.buildings),
            "gable_roofs": sum(b.gable for b in layout.buildings),
            "trees": len(layout.trees),
            "conifers": sum(t.conifer for t in layout.trees),
            "forest_trees": sum(t.forest for t in layout.trees),
            "hedges": len(layout.hedges),
            "roads": len(layout.roads),
            **{f"{kind}s": sum(o["kind"] == kind for o in objects) for kind in OBJECT_KINDS},
        },
        "labels": {"file": LABELS_FILE, "format": LABELS_FORMAT, "method": LABELS_METHOD},
        "sky_visibility": {"file": SKY_FILE, "format": SKY_FORMAT, "cache": True},
        "classes": class_table(),
        "objects": objects,
        "vegetation": vegetation_truth(layout, mesh.vertices, mesh.faces, labels.face_instance,
                                       len(layout.buildings) + 1),
    }


def build_demo_world(out_dir: str | os.PathLike, variant: str = "default", seed: int = 0) -> Path:
    """Generate the demo world ``variant`` ("default", "small" or "large") for ``seed`` into the scene folder ``out_dir``
    (created if missing; ``world.glb``, ``labels.npz`` and ``scene.json`` are replaced atomically). Same arguments,
    same bytes. ``scene.json`` names ``sky_visibility.npz`` as a cache: the first lit render bakes it, the later ones
    load it. Returns the folder."""
    _spec(variant)
    layout, mesh, atlas, labels, objects = generate_world(variant, seed)
    out = Path(out_dir)
    write_bytes_atomic(out / MESH_NAME, encode_glb(mesh, atlas))
    write_labels(out / LABELS_FILE, labels, stored_mesh_sha256(mesh))
    text = json.dumps(scene_description(layout, mesh, labels, variant, seed, objects), indent=2) + "\n"
    write_text_atomic(out / SCENE_JSON, text)
    return out


def default_cache_root() -> Path:
    """``$XDG_CACHE_HOME/aerostereo/worlds`` (``~/.cache/aerostereo/worlds`` when unset)."""
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "aerostereo" / "worlds"


def demo_scene_dir(variant: str = "default", seed: int = 0, cache_root: str | os.PathLike | None = None) -> Path:
    """The scene folder of the demo world, built on first use into ``<cache_root>/<variant>-<seed>-v<version>``
    (a temporary sibling folder renamed into place, so a half-built world is never seen) and reused afterwards."""
    _spec(variant)
    root = Path(cache_root) if cache_root is not None else default_cache_root()
    final = root / f"{variant}-{int(seed)}-v{GENERATOR_VERSION}"
    if (final / SCENE_JSON).is_file():
        return final
    root.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(dir=root, prefix=f".{final.name}."))
    os.chmod(staging, 0o755)
    try:
        build_demo_world(staging, variant, seed)
        try:
            os.replace(staging, final)
        except OSError:  # another process finished first (non-empty target): use its copy
            if not (final / SCENE_JSON).is_file():
                raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return final
