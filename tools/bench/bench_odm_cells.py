"""The twin's first surface against ODM's dense cloud, per 1 m cell and per class (canopy, low, ground): brighton_beach.

    .venv/bin/python tools/bench/bench_odm_cells.py [--data SHARED_DATA] [--work DIR] [--scene SCENE]
                                               [--candidate NAME ...] [--list-candidates]

brighton_beach (18 nadir DJI photos, EXIF GPS) is reconstructed at the CLI defaults of ``aerostereo-recon`` into
``WORK/defaults`` (resumed when already there), or ``--scene`` names a finished scene folder to measure instead
(no recon, no times). Each ``--candidate`` (see ``--list-candidates``) starts from a copy of the defaults' ``work/``
so that only the stages its options change are redone; its time counts the stages it shares at the defaults' time.

ODM's ``model.laz`` (OpenMVS dense cloud of the same photos, UTM 15N; a peer, not truth) is binned into 1 m cells:
the 95th-percentile height of each cell with at least ``--min-points`` points is its top, and its local ground is
the progressive morphological ground filter of the cloud (:func:`recon.semantics.ground.fit_ground`). A cell is
*canopy* where its top is more than 2 m above that ground, *low* from 0.5 to 2 m, *ground* below 0.5 m.

The twin is put on ODM's cloud by a yaw + translation: the ICP of bench_recon (:func:`tools.bench.bench_recon.yaw_icp`,
on a quarter of its first surface's 0.5 m samples over its observed area), then a coarse-to-fine search of yaw and
horizontal shift that best correlates the twin's texture with ODM's point colours, and the vertical shift that puts
it on ODM's ground cells. The ICP alone does not settle on this flat park: its yaw drifts by 1.5 deg between 40 and
200 iterations, and after 40 it leaves the twin about 11 m off (roads cross lawns in a checkerboard overlay); the
colour fit puts the same roads on each other. Candidates with the defaults' SfM share its frame and alignment.
Then, for every ODM cell whose centre lies in the twin's observed area (``scene.json``), a ray cast straight down the
twin finds its first surface from above: a miss is a *hole*; otherwise the distance is |twin - ODM top|. Per
class: cells, holes share, median and p90 |distance| over the cells hit, and the share within 1 m (of all the
class's cells: a hole is not within).

Table: one row per scene: recon seconds per stage group (a candidate's shared stages at the defaults' time), the
ICP's and the refined yaw and how far the refinement moved the twin, then the figures per class.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import laspy  # noqa: E402
import numpy as np  # noqa: E402
import pycolmap  # noqa: E402

from cliutil.atomic import write_text_atomic  # noqa: E402
from cliutil.errors import BadInput  # noqa: E402
from cliutil.jsonfile import read_json  # noqa: E402
from cliutil.program import Parser, run_cli  # noqa: E402
from recon.run.cli_options import add_recon_options, recon_options  # noqa: E402
from recon.run.pipeline import Recon, ReconOptions  # noqa: E402
from recon.semantics.ground import GroundFilter, fit_ground  # noqa: E402
from recon.surface.grid import Grid  # noqa: E402
from recon.surface.mesh import per_cell_percentile  # noqa: E402
from recon.surface.observed import inside  # noqa: E402
from sim.render.raycast import from_above  # noqa: E402
from sim.render.shade import surface_albedo  # noqa: E402
from sim.render.scene import Scene, SceneError, load_scene  # noqa: E402
from tools.bench.bench_recon import YawShift, read_odm_cloud, yaw_icp  # noqa: E402

PROGRAM = "bench_odm_cells"
DEFAULT_DATA = Path(os.environ.get("AEROSTEREO_SHARED_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))
CLASSES = ("canopy", "low", "ground")
#: Cell of ODM's colour image that the twin's texture is aligned on (m).
COLOUR_CELL_M = 0.5
#: Height of ODM's top above its local ground (m) from which a cell is low, and canopy.
LOW_M, CANOPY_M = 0.5, 2.0
#: Stage groups of the time columns (recon.run.stages.STAGES).
STAGE_GROUPS = {"sfm": ("sfm",), "dense": ("undistort", "depth", "fusion"), "mesh": ("mesh",),
                "texture+": ("texture", "scene", "labels")}


def with_dense(**changes):
    """A candidate changing :class:`~recon.surface.dense.DenseOptions` fields."""
    return lambda options: dataclasses.replace(options, dense=dataclasses.replace(options.dense, **changes))


def with_options(first=lambda options: options, **changes):
    """A candidate changing ``ReconOptions`` fields (after ``first``, another candidate's change)."""
    return lambda options: dataclasses.replace(first(options), **changes)


#: Fusion that keeps points seen in 2 depth maps (default 3) with normals up to 45 deg apart (default 20).
LOOSE_FUSION = {"fusion_min_pixels": 2, "fusion_max_normal_error_deg": 45.0}

#: ``--candidate`` rows (docs/recon.md has their table): name -> (what changes, the defaults -> its options).
CANDIDATES: dict[str, tuple[str, object]] = {
    "2.5d": ("--mesh 2.5d (height field)", with_options(mesh="2.5d")),
    "standing": ("--standing heightfield (standing objects put back)", with_options(standing="heightfield")),
    "trim3": ("Poisson trim 3", with_options(poisson_trim=3.0)),
    "neighbours8": ("8 stereo neighbours", with_dense(num_neighbors=8)),
    "fusion2": ("fusion min 2 pixels, normal error 45 deg", with_dense(**LOOSE_FUSION)),
    "fusion2-trim3": ("fusion 2 pixels / 45 deg, Poisson trim 3",
                      with_options(with_dense(**LOOSE_FUSION), poisson_trim=3.0)),
    "fusion2-poisson11": ("fusion 2 pixels / 45 deg, Poisson depth 11",
                          with_options(with_dense(**LOOSE_FUSION), poisson_depth=11)),
    "fusion2-consistency5": ("fusion 2 pixels / 45 deg, consistency 5 %", with_dense(**LOOSE_FUSION, consistency=0.05)),
    "fusion2-dense1600": ("fusion 2 pixels / 45 deg, --dense-size 1600",
                          with_dense(**LOOSE_FUSION, max_image_size=1600)),
}


@dataclass(frozen=True)
class OdmCells:
    """ODM's cloud on 1 m cells of a :class:`~recon.surface.grid.Grid` (its own frame): the 95th-percentile height
    ``top_m`` (NaN where too few points), the local ground ``ground_m`` and the class index into :data:`CLASSES`."""

    grid: Grid
    top_m: np.ndarray
    ground_m: np.ndarray

    @property
    def measured(self) -> np.ndarray:
        return np.isfinite(self.top_m)

    def classes(self) -> np.ndarray:
        """``(rows, cols)`` index into :data:`CLASSES` by the top's height above the local ground."""
        above = np.where(self.measured, self.top_m - self.ground_m, 0.0)
        return np.where(above > CANOPY_M, 0, np.where(above > LOW_M, 1, 2))


def odm_cells(points: np.ndarray, cell_m: float = 1.0, percentile: float = 95.0, min_points: int = 3) -> OdmCells:
    """Bin ODM's ``(N, 3)`` cloud into cells: their top (``percentile`` of z where at least ``min_points`` fall)
    and the ground under them (:func:`fit_ground` on the same grid)."""
    ground = fit_ground(points, GroundFilter(cell_m=cell_m))
    grid = ground.grid
    row, col = grid.cell_of(points[:, :2])
    cells = row * grid.cols + col
    top = per_cell_percentile(cells, points[:, 2], grid.rows * grid.cols, percentile)
    top[np.bincount(cells, minlength=grid.rows * grid.cols) < min_points] = np.nan
    return OdmCells(grid, top.reshape(grid.rows, grid.cols), ground.height_m)


def observed_polygon(scene: Scene) -> np.ndarray:
    """The twin's observed area (ENU ``(K, 2)``), as ``scene.json`` stores it."""
    if scene.observed_area_m is None:
        raise BadInput(f"{scene.source}: scene.json has no observed_area_m (a recon scene with its cameras expected)")
    return np.asarray(scene.observed_area_m, dtype=np.float64)


@dataclass(frozen=True)
class TwinSamples:
    """The twin's first surface from above on a regular grid over its observed area: ``(N, 3)`` ENU points and the
    grey level (linear albedo, the mean of R, G, B) of the texture there."""

    points: np.ndarray
    grey: np.ndarray


def twin_samples(scene: Scene, spacing_m: float) -> TwinSamples:
    """:class:`TwinSamples` every ``spacing_m`` over the twin's observed area (the rays that miss left out)."""
    polygon = observed_polygon(scene)
    xy = Grid.covering(polygon, spacing_m).centres()
    xy = xy[inside(polygon, xy)]
    heights, hits = from_above(scene, xy)
    hit = hits.hit
    grey = surface_albedo(scene, hits.tri[hit], hits.u[hit], hits.v[hit]).mean(axis=1)
    return TwinSamples(np.column_stack([xy[hit], heights[hit]]), grey)


def read_odm_colours(path: Path) -> np.ndarray:
    """``(N, 3)`` sRGB colours in [0, 1] of a LAS/LAZ cloud's points (8- or 16-bit in the file)."""
    las = laspy.read(path)
    rgb = np.column_stack([las.red, las.green, las.blue]).astype(np.float64)
    return rgb / (65535.0 if rgb.max() > 255 else 255.0)


def odm_grey(points: np.ndarray, srgb: np.ndarray, cell_m: float) -> tuple[Grid, np.ndarray]:
    """ODM's ``(N, 3)`` cloud with its ``srgb`` colours as a grey image of ``cell_m`` cells (the mean linear grey of
    each cell's points; NaN where none): its grid (in the cloud's frame) and the ``(rows, cols)`` values."""
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4).mean(axis=1)
    grid = Grid.covering(points[:, :2], cell_m)
    row, col = grid.cell_of(points[:, :2])
    cells = row * grid.cols + col
    counts = np.bincount(cells, minlength=grid.rows * grid.cols)
    with np.errstate(invalid="ignore"):
        grey = np.bincount(cells, weights=linear, minlength=grid.rows * grid.cols) / counts
    return grid, grey.reshape(grid.rows, grid.cols)


def value_at(grid: Grid, values: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """``values`` (``(rows, cols)`` of ``grid``) of the cell holding each ``(N, 2)`` point; NaN off the grid."""
    row, col = grid.cell_of(xy)
    on_grid = (row == np.floor((grid.y0_m - xy[:, 1]) / grid.cell_m)) & \
        (col == np.floor((xy[:, 0] - grid.x0_m) / grid.cell_m))
    return np.where(on_grid, values[row, col], np.nan)


def correlation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pearson correlation of each row of ``a`` with the same row of ``b`` (``(M, N)``), over the pairs both hold."""
    both = np.isfinite(a) & np.isfinite(b)
    count = np.maximum(both.sum(axis=1), 1)
    a, b = np.where(both, a, 0.0), np.where(both, b, 0.0)
    a_mean, b_mean = (a.sum(axis=1) / count)[:, None], (b.sum(axis=1) / count)[:, None]
    a, b = np.where(both, a - a_mean, 0.0), np.where(both, b - b_mean, 0.0)
    return (a * b).sum(axis=1) / np.sqrt((a * a).sum(axis=1) * (b * b).sum(axis=1) + 1e-30)


def refine_on_colour(fit: YawShift, samples: TwinSamples, grid: Grid, grey: np.ndarray, steps: int = 11,
                     spans=((4.0, 8.0), (0.8, 1.6), (0.16, 0.32), (0.04, 0.08))) -> YawShift:
    """``fit`` refined by a coarse-to-fine search of the yaw (+-span degrees about the twin's centre) and the
    horizontal shift (+-span m) that best correlate the twin's texture (``samples``) with ODM's colours (``grey``
    on ``grid``): the roads, lawns and shadows of a park pin the twin down where its heights do not."""
    for yaw_span_deg, shift_span_m in spans:
        offsets = np.linspace(-shift_span_m, shift_span_m, steps)
        shifts = np.column_stack([a.ravel() for a in np.meshgrid(offsets, offsets)])
        best = (-np.inf, fit)
        for yaw in fit.yaw + np.radians(np.linspace(-yaw_span_deg, yaw_span_deg, steps)):
            moved = dataclasses.replace(fit, yaw=float(yaw)).apply(samples.points)
            xy = (moved[None, :, :2] + shifts[:, None, :]).reshape(-1, 2)
            score = correlation(np.broadcast_to(samples.grey, (len(shifts), len(moved))),
                                value_at(grid, grey, xy).reshape(len(shifts), len(moved)))
            k = int(np.argmax(score))
            if score[k] > best[0]:
                best = (score[k], dataclasses.replace(fit, yaw=float(yaw), shift=fit.shift + np.append(shifts[k], 0.0)))
        fit = best[1]
    return fit


def level_on_ground(fit: YawShift, samples: TwinSamples, odm: OdmCells) -> YawShift:
    """``fit`` with the vertical shift that puts the twin's first surface on ODM's ground cells (median)."""
    moved = fit.apply(samples.points)
    row, col = odm.grid.cell_of(moved[:, :2])
    ground = (odm.classes()[row, col] == CLASSES.index("ground")) & odm.measured[row, col]
    dz = np.median(moved[ground, 2] - value_at(odm.grid, odm.top_m, moved[ground, :2]))
    return dataclasses.replace(fit, shift=fit.shift - np.array([0.0, 0.0, dz]))


def align_twin(scene: Scene, reference: np.ndarray, odm: OdmCells, colours: tuple[Grid, np.ndarray]) \
        -> tuple[YawShift, YawShift]:
    """The yaw + translation putting the twin (ENU) on ODM's cloud, as the ICP of its first surface over its observed
    area found it (:func:`yaw_icp`), and then refined on colour (:func:`refine_on_colour`) and levelled on the
    ground (:func:`level_on_ground`): point-to-point ICP slides on flat ground (on brighton_beach its yaw drifts by
    1.5 deg between 40 and 200 iterations), and the heights of a flat park pin no yaw either."""
    samples = twin_samples(scene, 0.5)
    icp = yaw_icp(samples.points[::4], reference)
    return icp, level_on_ground(refine_on_colour(icp, samples, *colours), samples, odm)


def cell_distances(scene: Scene, odm: OdmCells, fit: YawShift) -> tuple[np.ndarray, np.ndarray]:
    """For ODM's measured cells whose centre falls in the twin's observed area: their class and the signed
    distance twin - ODM top (m; NaN = a hole, no twin surface under the ray)."""
    rows, cols = np.nonzero(odm.measured)
    centres = odm.grid.centres().reshape(odm.grid.rows, odm.grid.cols, 2)[rows, cols]
    top = odm.top_m[rows, cols]
    twin_xyz = fit.invert(np.column_stack([centres, top]))  # the cell's vertical line in the twin's frame
    keep = inside(observed_polygon(scene), twin_xyz[:, :2])
    twin_xyz = twin_xyz[keep]
    height = scene.ground_height(twin_xyz[:, 0], twin_xyz[:, 1])
    on_odm = fit.apply(np.column_stack([twin_xyz[:, :2], np.nan_to_num(height)]))[:, 2]
    return odm.classes()[rows, cols][keep], np.where(np.isfinite(height), on_odm - top[keep], np.nan)


def class_figures(classes: np.ndarray, distance: np.ndarray) -> dict[str, dict[str, float]]:
    """Per class: cells, holes share, median and p90 |distance| over the cells hit, share within 1 m (holes not)."""
    figures = {}
    for index, name in enumerate(CLASSES):
        d = np.abs(distance[classes == index])
        hit = d[np.isfinite(d)]
        figures[name] = {"cells": len(d), "holes": float(np.mean(np.isnan(d))) if len(d) else np.nan,
                         "median": float(np.median(hit)) if len(hit) else np.nan,
                         "p90": float(np.percentile(hit, 90)) if len(hit) else np.nan,
                         "within_1m": float(np.mean(hit <= 1.0) * len(hit) / len(d)) if len(d) else np.nan}
    return figures


def measure(scene_dir: Path, odm: OdmCells, reference: np.ndarray, colours: tuple[Grid, np.ndarray],
            aligned: dict | None = None) -> dict:
    """:func:`class_figures` of one scene folder against ODM with the ICP's and the refined yaw (degrees) and how far
    the refinement moved the twin (m). ``aligned``: the measure of a scene with the same SfM stage, whose alignment
    is taken over (same frame; the comparison of later-stage options then carries no alignment noise)."""
    scene = load_scene(scene_dir, with_labels=False)
    icp, fit = (aligned["icp"], aligned["fit"]) if aligned else align_twin(scene, reference, odm, colours)
    classes, distance = cell_distances(scene, odm, fit)
    return {"figures": class_figures(classes, distance), "icp": icp, "fit": fit, "icp_yaw_deg": np.degrees(icp.yaw),
            "yaw_deg": np.degrees(fit.yaw), "refined_m": float(np.linalg.norm(fit.shift[:2] - icp.shift[:2])),
            "sfm": sfm_fingerprint(scene_dir)}


def sfm_fingerprint(scene_dir: Path) -> str | None:
    """The fingerprint of a recon scene's SfM stage (None without a stamp): same fingerprint, same frame."""
    stamp = scene_dir / "work" / "stages" / "sfm.json"
    return read_json(stamp)["fingerprint"] if stamp.is_file() else None


def reconstruct(photo_dir: Path, scene_dir: Path, options: ReconOptions, start_from: Path | None) -> dict:
    """Run recon into ``scene_dir`` (from a copy of ``start_from``'s ``work/`` when given and the scene is new);
    the seconds of each stage, those of a stage done already taken from ``SCENE/bench_seconds.json`` (written here)
    or 0 where unknown."""
    if start_from is not None and not scene_dir.exists():
        shutil.copytree(start_from / "work", scene_dir / "work")
    run = Recon(photo_dir, None, scene_dir, options,
                log=lambda message: print(f"[{scene_dir.name}] {message}", file=sys.stderr, flush=True))
    run.run()
    stored = scene_dir / "bench_seconds.json"
    seconds = read_json(stored) if stored.is_file() else {}
    seconds |= {stage: value for stage, value in run.seconds.items() if value or stage not in seconds}
    write_text_atomic(stored, json.dumps(seconds, indent=2))
    return seconds


def stage_times(seconds: dict | None, baseline: dict | None) -> dict[str, float] | None:
    """Seconds per :data:`STAGE_GROUPS` group, a stage this run did not redo counted at the baseline's time."""
    if seconds is None:
        return None
    base = baseline or {}
    return {group: sum(seconds.get(stage) or base.get(stage, 0.0) for stage in stages)
            for group, stages in STAGE_GROUPS.items()}


def print_table(rows: list[dict]) -> None:
    groups = list(STAGE_GROUPS)
    headers = ["scene", *(f"{g} s" for g in groups), "total s", "yaw deg ICP / refined / refinement's move m",
               *(f"{c} cells, holes %, within 1 m %, median / p90 m" for c in CLASSES)]
    print("| " + " | ".join(headers) + " |\n" + "|---" * len(headers) + "|")
    for row in rows:
        times = row["times"]
        time_cells = [f"{times[g]:.0f}" for g in groups] + [f"{sum(times.values()):.0f}"] if times else \
            ["-"] * (len(groups) + 1)
        alignment = f"{row['icp_yaw_deg']:+.2f} / {row['yaw_deg']:+.2f} / {row['refined_m']:.1f}"
        class_cells = [f"{f['cells']}, {100 * f['holes']:.1f}, {100 * f['within_1m']:.1f}, "
                       f"{f['median']:.2f} / {f['p90']:.2f}" for f in (row["figures"][c] for c in CLASSES)]
        print("| " + " | ".join([row["label"], *time_cells, alignment, *class_cells]) + " |", flush=True)


def main(argv=None) -> int:
    return run_cli(PROGRAM, lambda: bench(argv), bad_input=(SceneError,))


def bench(argv) -> int:
    """The benchmark (module docstring); the table on stdout, recon's progress on stderr."""
    parser = Parser(prog=PROGRAM, description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA, help="the shared data folder (brighton_beach/)")
    parser.add_argument("--work", type=Path, default=Path("/tmp/bench_odm_cells"),
                        help="scene folders (defaults/, one per candidate; resumed)")
    parser.add_argument("--scene", type=Path, help="measure this finished scene instead of reconstructing defaults")
    parser.add_argument("--candidate", choices=sorted(CANDIDATES), action="append", default=[],
                        help="also reconstruct and measure this candidate (repeat)")
    parser.add_argument("--list-candidates", action="store_true", help="print the candidates and exit")
    parser.add_argument("--min-points", type=int, default=3, help="ODM points a cell needs (default 3)")
    args = parser.parse_args(argv)
    pycolmap.logging.minloglevel = 2  # COLMAP's own log off: progress comes from recon's stages
    if args.list_candidates:
        for name, (what, _) in CANDIDATES.items():
            print(f"{name}: {what}")
        return 0
    photo_dir, laz = args.data / "brighton_beach" / "images", args.data / "brighton_beach" / "model.laz"
    for path in (*([args.scene / "scene.json"] if args.scene else []), photo_dir, laz):
        if not path.exists():
            parser.error(f"{path}: not found (expected {'a recon scene folder' if args.scene else 'the shared data'})")
    reference = read_odm_cloud(laz)
    odm = odm_cells(reference, min_points=args.min_points)
    colours = odm_grey(reference, read_odm_colours(laz), COLOUR_CELL_M)
    defaults = recon_options(cli_defaults())
    if args.scene:
        base_dir, base_seconds = args.scene, None
    else:
        base_dir = args.work / "defaults"
        base_seconds = reconstruct(photo_dir, base_dir, defaults, None)
    label = f"given scene {base_dir}" if args.scene else "CLI defaults"
    rows = [{"label": label, "times": stage_times(base_seconds, None),
             **measure(base_dir, odm, reference, colours)}]
    for name in args.candidate:
        what, change = CANDIDATES[name]
        seconds = reconstruct(photo_dir, args.work / name, change(defaults), base_dir)
        same_frame = rows[0] if sfm_fingerprint(args.work / name) == rows[0]["sfm"] else None
        rows.append({"label": what, "times": stage_times(seconds, base_seconds) if base_seconds else None,
                     **measure(args.work / name, odm, reference, colours, same_frame)})
    print_table(rows)
    return 0


def cli_defaults() -> argparse.Namespace:
    """``aerostereo-recon``'s options as a user who gives none gets them."""
    parser = argparse.ArgumentParser()
    add_recon_options(parser)
    return parser.parse_args([])


if __name__ == "__main__":
    sys.exit(main())
