"""Our surface classes (:mod:`sim.render.classes`) in the class tables of other datasets, for the exports.

* **Virtual KITTI 2** (``textgt``'s ``colors.txt``: ``Category r g b``, one line per class): its class images
  (``classgt_NNNNN.png``) are 8-bit RGB, each pixel its class's colour.
* **Cityscapes** (the label table of ``cityscapesscripts/helpers/labels.py``), which KITTI's semantic and instance
  segmentation benchmark uses: class images hold the ``labelId``, ``semantic_rgb`` images its colour.

Neither table has water: it is written as their no-class value (VKITTI2 ``Undefined``, Cityscapes ``unlabeled``), as
``unknown`` is, so that a model trained on the export learns it as nothing rather than as some other class. Our
``other`` (clutter) is VKITTI2's ``Misc`` and Cityscapes' ``static`` (void: stationary things of no other class,
ignored by its evaluation). Roofs, walls and chimneys are ``Building``/``building``: Cityscapes' ``wall`` is a
free-standing wall, not a building's; trees are VKITTI2's ``Tree`` and Cityscapes' ``vegetation``; fields are
VKITTI2's ``Vegetation`` (low plants) and Cityscapes' ``terrain`` (grass, soil), where our ``ground`` goes too.
Poles (street lamps with their arms, as Cityscapes counts a pole's horizontal part) are ``Pole``/``pole``; cars are
``Car``/``car``; fences are Cityscapes' ``fence`` and VKITTI2's ``GuardRail``, its only barrier along a road. Neither
table has wires: they are ``Misc``/``static``, like clutter.
"""

from __future__ import annotations

import numpy as np

from sim.render.classes import CLASSES

#: VKITTI2's classes in the order of its ``colors.txt``: name and RGB colour.
VKITTI2_COLOURS: tuple[tuple[str, tuple[int, int, int]], ...] = (
    ("Terrain", (210, 0, 200)), ("Sky", (90, 200, 255)), ("Tree", (0, 199, 0)), ("Vegetation", (90, 240, 0)),
    ("Building", (140, 140, 140)), ("Road", (100, 60, 100)), ("GuardRail", (250, 100, 255)),
    ("TrafficSign", (255, 255, 0)), ("TrafficLight", (200, 200, 0)), ("Pole", (255, 130, 0)), ("Misc", (80, 80, 80)),
    ("Truck", (160, 60, 60)), ("Car", (255, 127, 80)), ("Van", (0, 139, 139)), ("Undefined", (0, 0, 0)))
#: Each of our classes (by name) as a VKITTI2 class.
TO_VKITTI2 = {"unknown": "Undefined", "ground": "Terrain", "road": "Road", "roof": "Building", "wall": "Building",
              "tree": "Tree", "field": "Vegetation", "water": "Undefined", "other": "Misc", "sky": "Sky",
              "chimney": "Building", "pole": "Pole", "wire": "Misc", "fence": "GuardRail", "car": "Car"}

#: The Cityscapes labels our classes become: name -> (labelId, RGB colour).
CITYSCAPES = {"unlabeled": (0, (0, 0, 0)), "static": (4, (0, 0, 0)), "road": (7, (128, 64, 128)),
              "building": (11, (70, 70, 70)), "fence": (13, (190, 153, 153)), "pole": (17, (153, 153, 153)),
              "vegetation": (21, (107, 142, 35)), "terrain": (22, (152, 251, 152)), "sky": (23, (70, 130, 180)),
              "car": (26, (0, 0, 142))}
#: Each of our classes (by name) as a Cityscapes label.
TO_CITYSCAPES = {"unknown": "unlabeled", "ground": "terrain", "road": "road", "roof": "building", "wall": "building",
                 "tree": "vegetation", "field": "terrain", "water": "unlabeled", "other": "static", "sky": "sky",
                 "chimney": "building", "pole": "pole", "wire": "static", "fence": "fence", "car": "car"}


def _lookup(values: dict, dtype) -> np.ndarray:
    """An array indexed by our class id holding ``values[class name]``."""
    return np.array([values[surface_class.name] for surface_class in CLASSES], dtype=dtype)


#: Class id image -> VKITTI2 ``classgt`` RGB image: ``VKITTI2_RGB[classes]``.
VKITTI2_RGB = _lookup({ours: dict(VKITTI2_COLOURS)[theirs] for ours, theirs in TO_VKITTI2.items()}, np.uint8)
#: Class id image -> Cityscapes labelId image: ``CITYSCAPES_ID[classes]``.
CITYSCAPES_ID = _lookup({ours: CITYSCAPES[theirs][0] for ours, theirs in TO_CITYSCAPES.items()}, np.uint8)
#: Class id image -> Cityscapes colour image: ``CITYSCAPES_RGB[classes]``.
CITYSCAPES_RGB = _lookup({ours: CITYSCAPES[theirs][1] for ours, theirs in TO_CITYSCAPES.items()}, np.uint8)


def vkitti2_colors_text() -> str:
    """VKITTI2's ``colors.txt``: the header ``Category r g b`` and one ``Name r g b`` line per class."""
    return "".join(["Category r g b\n", *(f"{name} {r} {g} {b}\n" for name, (r, g, b) in VKITTI2_COLOURS)])
