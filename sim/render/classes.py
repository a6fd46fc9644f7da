"""The surface classes of a scene's faces and of the class images rendered from them: ids, names, palette, groups.

One table for every scene, demo world or twin: the ids are what ``semantic_N/`` images hold (uint8), the palette is
what contact sheets and ``semantic_rgb`` exports paint them with, and :data:`GROUPS` are the coarse classes a twin's
labels are measured in (ground / building / vegetation / objects: what geometry and colour can tell apart from the
air). Fields of crops and lawns are ground cover, so they belong to the ground group, as Cityscapes files grass and
soil under "terrain", and so does water, a flat surface at the ground's level; trees are the vegetation group.
Chimneys are part of the built mass (building group) but a class of their own, so that a twin's chimneys can be
counted; poles, wires, fences and cars are the small things a twin loses first, the objects group.

Ids 0-9 are the table of the first labelled datasets; later classes are appended (10-14), never renumbered, so a class
image written with the earlier table still reads right.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SurfaceClass:
    """One class: its ``id`` (uint8 pixel value), ``name``, display colour ``rgb`` (sRGB uint8) and what it covers."""

    id: int
    name: str
    rgb: tuple[int, int, int]
    covers: str


CLASSES: tuple[SurfaceClass, ...] = (
    SurfaceClass(0, "unknown", (0, 0, 0), "no label, or the labeller was not sure enough to give one"),
    SurfaceClass(1, "ground", (152, 118, 84), "bare ground, lawn, yards, paths: terrain that is not road or field"),
    SurfaceClass(2, "road", (128, 64, 128), "paved or dirt roads and tracks"),
    SurfaceClass(3, "roof", (220, 60, 40), "building roofs"),
    SurfaceClass(4, "wall", (190, 153, 153), "building walls"),
    SurfaceClass(5, "tree", (0, 150, 0), "trees and tall bushes"),
    SurfaceClass(6, "field", (170, 220, 60), "crops, meadows: low vegetation covering the ground"),
    SurfaceClass(7, "water", (40, 90, 220), "open water"),
    SurfaceClass(8, "other", (255, 200, 0), "labelled surfaces of no class in this table (clutter)"),
    SurfaceClass(9, "sky", (135, 206, 235), "pixels whose ray hits nothing"),
    SurfaceClass(10, "chimney", (120, 40, 30), "chimneys standing on roofs"),
    SurfaceClass(11, "pole", (153, 153, 153), "poles and posts: street lamps (arm and lamp included), power poles "
                                              "(crossarm included)"),
    SurfaceClass(12, "wire", (255, 0, 255), "overhead wires"),
    SurfaceClass(13, "fence", (200, 140, 60), "fences and their posts"),
    SurfaceClass(14, "car", (0, 0, 142), "cars and other road vehicles"),
)
BY_NAME = {surface_class.name: surface_class for surface_class in CLASSES}
UNKNOWN = BY_NAME["unknown"].id
GROUND = BY_NAME["ground"].id
ROAD = BY_NAME["road"].id
ROOF = BY_NAME["roof"].id
WALL = BY_NAME["wall"].id
TREE = BY_NAME["tree"].id
FIELD = BY_NAME["field"].id
WATER = BY_NAME["water"].id
OTHER = BY_NAME["other"].id
SKY = BY_NAME["sky"].id
CHIMNEY = BY_NAME["chimney"].id
POLE = BY_NAME["pole"].id
WIRE = BY_NAME["wire"].id
FENCE = BY_NAME["fence"].id
CAR = BY_NAME["car"].id
#: The coarse classes a twin is measured in, each a tuple of class ids.
GROUPS: dict[str, tuple[int, ...]] = {"ground": (GROUND, ROAD, FIELD, WATER), "building": (ROOF, WALL, CHIMNEY),
                                      "vegetation": (TREE,), "objects": (POLE, WIRE, FENCE, CAR)}


def class_table() -> list[dict]:
    """The table as ``dataset.json`` and ``scene.json`` list it: one ``{"id", "name", "rgb", "covers"}`` per class."""
    return [{"id": c.id, "name": c.name, "rgb": list(c.rgb), "covers": c.covers} for c in CLASSES]
