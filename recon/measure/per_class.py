"""A reconstructed twin against the true world per TRUE class and per small object, at the oblique views of
:mod:`recon.measure.oblique`.

The true world's face labels (:class:`sim.render.labels.SceneLabels`) give each pixel of a true view the class and
object of the face it hits. Over the in-area pixels of a class (:func:`recon.measure.oblique.in_area_mask`), per
view and pooled over views by summing pixel counts (never by averaging per-view ratios: a chimney may cover 30
pixels in one view and 3 in the next): the class's share of the in-area pixels, the twin's coverage (the pixel
shows twin surface, whatever it is: a twin that lost a car over a lawn covers the car's pixels with the lawn), the
depth abs rel |z_twin - z_true| / z_true over the covered pixels (median and mean), the share of pixels off, i.e.
with a depth off by more than :data:`OFF_FRACTION` or a hole (and farther than :data:`NEAR_M` from the true surface,
or a hole), and formula 3 over the covered pixels. Classes are reported one by one
(:data:`sim.render.classes.CLASSES`) and in the coarse :data:`sim.render.classes.GROUPS`.

Per object, for the small things (:data:`SMALL_KINDS`, scene.json's ``"objects"`` kinds): an object whose centre
lies in the observed area is SEEN where it has at least :data:`SEEN_PIXELS` in-area pixels pooled over the views,
RECOVERED where at least half of them have twin depth within :data:`OFF_FRACTION` (the issue's criterion), and
recovered NEAR where at least half are within :data:`NEAR_M` of the true surface (:func:`surface_distance`): at
20-100 m, a 1.5 m car or a 1 m chimney that the twin lost leaves the ground or roof behind it within 20 % of its depth,
so only the metric test tells a kept car from a lost one. Wires (:data:`COVERAGE_KINDS`) are too thin to judge per
object: their pixels and coverage only.

Frames and units: depths planar metres of the world; the twin's are scaled by ``depth_scale``
(:attr:`recon.measure.oblique.TwinFrame.scale`); object centres world ENU metres.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from recon.measure.oblique import in_area_mask
from recon.surface.observed import inside
from sim.evaluation.realism import photorealism_error_masked
from sim.render.camera import camera_rays
from sim.render.classes import CLASSES, GROUPS
from sim.render.labels import SceneLabels
from sim.render.renderer import View
from sim.render.scene import Scene

#: A covered pixel is off where its twin depth differs from the true one by more than this fraction of the true one.
OFF_FRACTION = 0.2
#: The metric tolerance of the NEAR count (m), on the twin's distance from the true surface's tangent plane
#: (:func:`surface_distance`): loose against the twin's few-cm shape error, tight against the metre between a lost
#: car's or chimney's top and the ground or roof under it.
NEAR_M = 0.5
#: Pooled in-area pixels an object needs to be judged: below about 20 most of its pixels are silhouette pixels, where
#: a sub-pixel shift of the twin's edge decides, and "half of them" is a handful of pixels.
SEEN_PIXELS = 20
#: scene.json object kinds judged per object (recovered or not), and those reported by coverage only.
SMALL_KINDS = ("chimney", "lamp_post", "power_pole", "car")
COVERAGE_KINDS = ("wire",)


@dataclass(frozen=True)
class PixelTally:
    """One class's in-area pixels in one view, or pooled: ``pixels``; ``covered``: those where the twin has surface;
    ``within``: covered with depth within :data:`OFF_FRACTION`; ``near``: covered within :data:`NEAR_M` of the true
    surface (:func:`surface_distance`);
    ``error_sum``: formula 3 (%) over the covered ones
    times ``covered`` (so pooled formula 3 is ``error_sum / covered``); ``abs_rel``: float32 |z_twin - z_true| /
    z_true of each covered pixel (for the pooled median)."""

    pixels: int
    covered: int
    within: int
    near: int
    error_sum: float
    abs_rel: np.ndarray = field(repr=False)

    def __add__(self, other: PixelTally) -> PixelTally:
        return PixelTally(self.pixels + other.pixels, self.covered + other.covered, self.within + other.within,
                          self.near + other.near, self.error_sum + other.error_sum,
                          np.concatenate([self.abs_rel, other.abs_rel]))

    def summary(self, in_area: int) -> dict:
        """Share of the ``in_area`` pixels, coverage, abs rel median and mean over the covered pixels, the share off
        (depth off by more than :data:`OFF_FRACTION` or a hole), the share farther than :data:`NEAR_M` from the true
        surface or a hole, and formula 3 (%) over the covered pixels; NaN where a ratio has no pixels."""
        covered = self.covered > 0
        return {"pixels": self.pixels, "share": _ratio(self.pixels, in_area),
                "coverage": _ratio(self.covered, self.pixels),
                "abs_rel_median": float(np.median(self.abs_rel)) if covered else math.nan,
                "abs_rel_mean": float(np.mean(self.abs_rel, dtype=np.float64)) if covered else math.nan,
                "off": _ratio(self.pixels - self.within, self.pixels),
                "off_near": _ratio(self.pixels - self.near, self.pixels),
                "error_covered": self.error_sum / self.covered if covered else math.nan}


EMPTY = PixelTally(0, 0, 0, 0, 0.0, np.zeros(0, np.float32))


@dataclass(frozen=True)
class ClassView:
    """One view's scores per true class: ``in_area`` pixels in all, a :class:`PixelTally` per class id present, and
    per object of interest ``[pixels, covered, within, near]`` over its in-area pixels."""

    in_area: int
    classes: dict[int, PixelTally]
    objects: dict[int, np.ndarray]

    def to_dict(self) -> dict:
        """JSON-ready: per class name its :meth:`PixelTally.summary`."""
        return {"in_area": self.in_area,
                "classes": {CLASSES[c].name: t.summary(self.in_area) for c, t in sorted(self.classes.items())}}


def score_classes(true_view: View, twin_view: View, labels: SceneLabels, polygon: np.ndarray,
                  depth_scale: float = 1.0, instances: Iterable[int] = ()) -> ClassView:
    """The twin's view against the true one (same pose) per true class of ``labels`` (the true scene's), and per
    object of ``instances`` (ids of ``labels.face_instance``); ``depth_scale``: world metres per twin depth unit."""
    in_area = in_area_mask(true_view, polygon)
    face = np.where(in_area, true_view.triangle, 0)
    face_class, instance = labels.face_class[face], labels.face_instance[face]
    covered = in_area & twin_view.valid
    true_depth = np.where(in_area, true_view.depth, 1.0).astype(np.float64)  # finite where scored
    difference = np.abs(np.where(covered, twin_view.depth * np.float64(depth_scale), true_depth) - true_depth)
    abs_rel = difference / true_depth
    within, near = covered & (abs_rel <= OFF_FRACTION), covered & (surface_distance(true_view, difference) <= NEAR_M)
    classes = {}
    for class_id in np.unique(face_class[in_area]):
        mask = in_area & (face_class == class_id)
        covered_here = mask & covered
        error = photorealism_error_masked(true_view.rgb, twin_view.rgb, covered_here)
        count = int(covered_here.sum())
        classes[int(class_id)] = PixelTally(int(mask.sum()), count, int((mask & within).sum()),
                                            int((mask & near).sum()), error * count if count else 0.0,
                                            abs_rel[covered_here].astype(np.float32))
    return ClassView(int(in_area.sum()), classes, _object_counts(in_area, instance, (covered, within, near), instances))


def surface_distance(true_view: View, depth_difference: np.ndarray) -> np.ndarray:
    """(H, W) metres from the twin's point on each pixel's ray to the plane tangent to the true surface at the true
    point, given the planar ``depth_difference`` (m) between them: the distance along the ray (depth difference / the
    ray's cosine to the optical axis) times the ray's cosine to the true normal. A twin surface offset by d along its
    normal is d away at any viewing angle, where the distance along a grazing ray is many times d."""
    rays = camera_rays(true_view.camera, true_view.T_world_cam)
    incidence = np.abs(np.einsum("ij,ij->i", rays.directions, true_view.normal.reshape(-1, 3))) / rays.depth_scale
    return depth_difference * incidence.reshape(depth_difference.shape)


def _object_counts(in_area: np.ndarray, instance: np.ndarray, flags: tuple[np.ndarray, ...],
                   instances: Iterable[int]) -> dict[int, np.ndarray]:
    """Per object of ``instances`` seen in ``in_area``: its pixel count and the count of each of ``flags``."""
    mask = in_area & np.isin(instance, np.fromiter(instances, np.int64))
    ids, index = np.unique(instance[mask], return_inverse=True)
    counts = np.stack([np.bincount(index, minlength=len(ids))] +
                      [np.bincount(index, weights=flag[mask], minlength=len(ids)) for flag in flags], axis=1)
    return {int(i): row.astype(np.int64) for i, row in zip(ids, counts, strict=True)}


def pool_classes(views: Sequence[ClassView]) -> dict:
    """Pixel counts pooled over ``views``: ``{"in_area", "groups": {group: summary}, "classes": {name: summary}}``
    (:meth:`PixelTally.summary`; every group, the classes with pixels, in table order)."""
    in_area = sum(view.in_area for view in views)
    pooled: dict[int, PixelTally] = {}
    for view in views:
        for class_id, tally in view.classes.items():
            pooled[class_id] = pooled.get(class_id, EMPTY) + tally
    groups = {name: sum((pooled.get(c, EMPTY) for c in ids), EMPTY).summary(in_area) for name, ids in GROUPS.items()}
    return {"in_area": in_area, "groups": groups,
            "classes": {CLASSES[c].name: pooled[c].summary(in_area) for c in sorted(pooled)}}


def object_kinds(objects: Sequence[dict], source: str) -> dict[int, str]:
    """Instance id -> kind of scene.json's ``"objects"`` entries of :data:`SMALL_KINDS` and :data:`COVERAGE_KINDS`;
    ``ValueError`` naming ``source`` for an entry without an integer ``instance`` or a string ``kind``."""
    kinds = {}
    for index, entry in enumerate(objects):
        instance, kind = (entry.get("instance"), entry.get("kind")) if isinstance(entry, dict) else (None, None)
        if not isinstance(instance, int) or isinstance(instance, bool) or not isinstance(kind, str):
            raise ValueError(f"{source}: objects[{index}]: expected an integer 'instance' and a string 'kind'")
        if kind in SMALL_KINDS + COVERAGE_KINDS:
            kinds[instance] = kind
    return kinds


def objects_in_area(scene: Scene, instances: Iterable[int], polygon: np.ndarray) -> set[int]:
    """The objects of ``instances`` whose centre (mean of their faces' centroids, world ENU x, y) lies in the
    observed ``polygon``."""
    wanted = np.fromiter(instances, np.int64)
    if scene.labels is None or not len(wanted):
        return set()
    face_instance = scene.labels.face_instance.astype(np.int64)
    mask = np.isin(face_instance, wanted)
    ids, index = np.unique(face_instance[mask], return_inverse=True)
    centroids = scene.vertices[scene.faces[mask]].mean(axis=1)
    count = np.bincount(index, minlength=len(ids))
    centres = np.stack([np.bincount(index, centroids[:, axis], len(ids)) / count for axis in (0, 1)], axis=1)
    return {int(i) for i, centre in zip(ids, centres, strict=True) if inside(polygon, centre)}


def count_objects(views: Sequence[ClassView], kinds: dict[int, str], in_area: set[int]) -> dict:
    """Per kind present among ``kinds`` (instance -> kind), over its objects in the observed area (``in_area``) and
    their pixels pooled over ``views``: how many, seen, recovered (and NEAR), the share of the seen ones recovered,
    pixels and coverage; for :data:`COVERAGE_KINDS` pixels and coverage only (the others None). Also ``"objects"``:
    each such object's kind, pooled pixels and shares covered, within and near."""
    pooled: dict[int, np.ndarray] = {instance: np.zeros(4, np.int64) for instance in in_area if instance in kinds}
    for view in views:
        for instance, counts in view.objects.items():
            if instance in pooled:
                pooled[instance] += counts
    rows = {}
    for kind in (kind for kind in SMALL_KINDS + COVERAGE_KINDS if kind in kinds.values()):
        members = [pooled[i] for i in sorted(pooled) if kinds[i] == kind]
        pixels, covered = (int(sum(m[k] for m in members)) for k in (0, 1))
        row = {"in_area": len(members), "pixels": pixels, "coverage": _ratio(covered, pixels),
               "seen": None, "recovered": None, "recovered_near": None, "share_recovered": None}
        if kind in SMALL_KINDS:
            seen = [m for m in members if m[0] >= SEEN_PIXELS]
            recovered = sum(int(2 * m[2] >= m[0]) for m in seen)
            row.update(seen=len(seen), recovered=recovered, recovered_near=sum(int(2 * m[3] >= m[0]) for m in seen),
                       share_recovered=_ratio(recovered, len(seen)))
        rows[kind] = row
    objects = {str(i): {"kind": kinds[i], "pixels": int(m[0]), "covered": _ratio(m[1], m[0]),
                        "within": _ratio(m[2], m[0]), "near": _ratio(m[3], m[0])} for i, m in sorted(pooled.items())}
    return {"kinds": rows, "objects": objects}


def _ratio(part: float, whole: float) -> float:
    return float(part / whole) if whole else math.nan
