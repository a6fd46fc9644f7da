"""Recon knobs against time and error: the real DJI set (brighton_beach, 18 photos, EXIF GPS priors) and
virtual flights over the small demo world (known poses and surface).

    .venv/bin/python tools/bench/bench_recon.py [--sizes 800 1600] [--with-3200] [--dense-sizes 640 1000]
                                          [--no-synthetic] [--p4m-only [LABEL]] [--data SHARED_DATA]

Table 1, SfM image size on brighton_beach: time per stage, registered photos, 3-D points, mean reprojection
error, camera-centre residual RMS against EXIF GPS (east/north/up), time ratio to the first row. There is no
ground truth for the poses: the GPS residual is bounded by the GPS's own noise.
Table 1b, SfM image size on a virtual flight: the closed-loop orbit (24 photos) rendered at a DJI photo's
4000x3000, so that every size is a real downscale; time per stage against the camera position and rotation
error and the focal length error against the virtual drone's truth.
Table 2, dense image size (whole pipeline, SfM at 1000 px): dense/mesh stage times and the distance of the
fused cloud and of the 2.5-D mesh vertices to ODM's reference cloud ``model.laz`` (UTM 15N), after a
yaw + translation ICP (our ENU frame and ODM's UTM grid differ by the meridian convergence, ~0.7 deg here,
and by their GPS/datum offsets), texture time and the photorealism error (formula 3, over the pixels the mesh
covers) of unlit renders from the recovered poses against the undistorted photos (the paper: 12.49 %).
Table 4, p4m_rtk (32 nadir DJI FC6360 photos 1600x1300, RTK fixed, factory calibration in XMP), SfM before
(main: focal seeded from EXIF, consumer-GPS prior sigmas) and after (factory camera, the receivers' own
sigmas), and the choices behind the default (fixed vs refined factory intrinsics, k3, which focal): time
against the camera positions' RMS per axis to the RTK positions, the rotation to the XMP gimbal attitude and
the final focal length.
Table 3, the closed loop: a 24-photo orbit over the small demo world (tools/loops/virtual_flight.py), SfM once,
then dense/meshing/texture options, each against the true poses and surface.
The 30-minute target (one full default orbit, 452 photos) is measured by tools/bench/bench_recon_orbit.py.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import laspy  # noqa: E402
import numpy as np  # noqa: E402
import pycolmap  # noqa: E402
import trimesh  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

from recon.surface.dense import DenseOptions  # noqa: E402
from recon.measure.evaluate import scene_photorealism  # noqa: E402
from recon.run.pipeline import Recon, ReconOptions, read_rgb  # noqa: E402
from recon.appearance.texture import TextureOptions  # noqa: E402

from capture.attitude import camera_matrix_world  # noqa: E402
from capture.logs.photos import read_camera_xmp, read_photo  # noqa: E402
from recon.inputs.priors import (CameraSeed, camera_seed, focal_seed, list_photos, priors_from_exif,  # noqa: E402
                                 read_geotags)
from recon.sfm.cameras import camera_poses  # noqa: E402
from recon.sfm.options import SfmError, SfmOptions  # noqa: E402
from recon.sfm.pipeline import run_sfm  # noqa: E402
from recon.inputs.similarity import umeyama  # noqa: E402
from sim.render.scene import load_scene  # noqa: E402
from sim.worlds import demo_scene_dir  # noqa: E402
from tools.loops.virtual_flight import INNER_RADIUS_M, Orbit, fly, height_errors, reuse_stages  # noqa: E402

DEFAULT_DATA = Path(os.environ.get("AEROSTEREO_SHARED_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))


def timed_sfm(photo_dir: Path, names, priors, size: int, features: int, seed=None, focal: str = "auto") -> dict:
    """One SfM run at ``size`` px (camera ``seed``, default: the focal seeded from the first photo) in a scratch
    folder: the size, the wall time, the report and the camera poses (``T_world_cam`` by name)."""
    seed = seed or focal_seed(photo_dir / names[0])
    with tempfile.TemporaryDirectory() as work:
        t0 = time.perf_counter()
        rec, report = run_sfm(photo_dir, names, priors, seed, Path(work),
                              SfmOptions(max_image_size=size, max_num_features=features, focal=focal))
        total = time.perf_counter() - t0
    return {"size": size, "total": total, "report": report, "poses": camera_poses(rec)}


def bench_size(photo_dir: Path, size: int, features: int) -> dict:
    names = list_photos(photo_dir)
    return timed_sfm(photo_dir, names, priors_from_exif(photo_dir, names), size, features)


def print_size_table(rows: list[dict], error_headers: list[str], error_cells) -> None:
    """SfM time per stage for each size row, the ratio to the first row, and the cells ``error_cells(row)``
    (one string per entry of ``error_headers``)."""
    base = rows[0]["total"]
    headers = ["max px", "extract s", "match s", "map s", "total s", "x first", "registered", "3-D pts",
               "reproj px", *error_headers]
    print("| " + " | ".join(headers) + " |\n" + "|---" * len(headers) + "|")
    for row in rows:
        r, s = row["report"], row["report"].seconds
        cells = [row["size"], f"{s['extract']:.1f}", f"{s['match']:.1f}", f"{s['map']:.1f}", f"{row['total']:.1f}",
                 f"{row['total'] / base:.2f}", f"{len(r.registered)}/{r.num_photos}", r.num_points3d,
                 f"{r.mean_reprojection_error_px:.2f}", *error_cells(row)]
        print("| " + " | ".join(str(cell) for cell in cells) + " |")


#: Table 1b's flight: the closed-loop orbit with photos of a DJI camera's size (12 MP, 4:3).
VIRTUAL_SFM_ORBIT_SIZE = (4000, 3000)


def bench_sizes_virtual(sizes, features: int) -> tuple[list[dict], Orbit]:
    """SfM at each of ``sizes`` on one virtual orbit of 4000x3000 photos; each row gains its pose errors
    against the truth (``errors``) and its final focal length error in % (``focal_error_pct``)."""
    orbit = Orbit(width=VIRTUAL_SFM_ORBIT_SIZE[0], height=VIRTUAL_SFM_ORBIT_SIZE[1])
    with tempfile.TemporaryDirectory() as work:
        flight = fly(load_scene(demo_scene_dir("small")), orbit, Path(work))
        priors = read_geotags(flight.geotags_csv)
        rows = [timed_sfm(flight.photo_dir, flight.names, priors, size, features) for size in sizes]
    for row in rows:
        row["errors"] = flight.pose_errors(row["poses"])
        row["focal_error_pct"] = 100 * (row["report"].focal_final_px / flight.camera.fx - 1)
    return rows, orbit


def p4m_rtk_variants(photo_dir: Path, names):
    """Table 4's rows: (label, camera seed, priors, ``SfmOptions.focal``). The priors' positions are the RTK
    positions (XMP) either way; "GPS sigmas" gives every photo main's consumer-GPS sigma instead of its own. The
    factory variants change one thing of the default seed (:func:`recon.inputs.priors.camera_seed`) each."""
    priors = priors_from_exif(photo_dir, names)
    gps = dataclasses.replace(priors, sigma_m=None)
    factory = camera_seed(photo_dir / names[0])
    calibration = read_camera_xmp(photo_dir / names[0]).calibration
    p1, p2 = calibration.dewarp[6:8]

    def variant(source: str, **params) -> CameraSeed:
        """The default factory seed with some FULL_OPENCV parameters replaced (by name)."""
        values = dict(zip(FULL_OPENCV_PARAMS, factory.params)) | params
        return dataclasses.replace(factory, params=tuple(values[name] for name in FULL_OPENCV_PARAMS), source=source)

    opencv = dataclasses.replace(factory, model="OPENCV", params=factory.params[:8], source="DewarpData, no k3")
    exif = focal_seed(photo_dir / names[0])
    return [("main: EXIF focal, GPS sigmas", exif, gps, "auto"),
            ("main, focal refined", exif, gps, "refine"),
            ("EXIF focal, RTK sigmas", exif, priors, "auto"),
            ("factory fixed, RTK sigmas (default)", factory, priors, "auto"),
            ("factory refined (focal, distortion)", factory, priors, "refine"),
            ("factory with DewarpData's tangential p1, p2", variant("with p1, p2", p1=p1, p2=p2), priors, "auto"),
            ("factory with p1, p2 sign-flipped", variant("flipped p1, p2", p1=-p1, p2=-p2), priors, "auto"),
            ("factory OPENCV (no k3)", opencv, priors, "auto"),
            ("factory, principal point at the optical centre",
             variant("centred", cx=calibration.centre_px[0], cy=calibration.centre_px[1]), priors, "auto"),
            ("factory at CalibratedFocalLength",
             variant("CalibratedFocalLength", fx=calibration.focal_px, fy=calibration.focal_px), priors, "auto")]


#: COLMAP FULL_OPENCV's parameter names, in order.
FULL_OPENCV_PARAMS = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")


def bench_p4m_rtk(photo_dir: Path, size: int, features: int, only=None):
    """SfM on p4m_rtk for each of :func:`p4m_rtk_variants` (those whose label contains ``only``, if given),
    yielding rows as they finish: camera centres against the RTK positions (RMS per axis E/N/U, m) and rotations
    against the XMP gimbal attitude (degrees); a variant whose mapping fails yields its error instead."""
    names = list_photos(photo_dir)
    xmp = [read_photo(photo_dir / name).values for name in names]
    attitude = camera_matrix_world(*(np.array([v[f"gimbal_{a}_deg"] for v in xmp]) for a in ("yaw", "pitch", "roll")))
    for label, seed, priors, focal in p4m_rtk_variants(photo_dir, names):
        if only and only not in label:
            continue
        t0 = time.perf_counter()
        try:
            row = timed_sfm(photo_dir, names, priors, size, features, seed, focal)
        except SfmError as error:
            yield {"label": label, "seed": seed, "total": time.perf_counter() - t0, "error": str(error)}
            continue
        done = [i for i, name in enumerate(names) if name in row["poses"]]
        centres = np.array([row["poses"][names[i]][:3, 3] for i in done])
        rotations = np.array([row["poses"][names[i]][:3, :3] for i in done])
        cos = (np.einsum("nij,nij->n", rotations, attitude[done]) - 1.0) / 2.0
        row.update(label=label, seed=seed,
                   rms_enu=np.sqrt(np.mean((centres - priors.positions_enu[done]) ** 2, axis=0)),
                   rotation_deg=np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
        yield row


def print_p4m_rtk_table(rows, size: int, factory_focal: tuple[float, float]) -> None:
    """Table 4, a line per row as it comes (``rows`` may be a generator)."""
    print(f"\np4m_rtk, 32 photos 1600x1300, SfM {size} px; truth: RTK positions (sigma ~1/1/2 cm) and "
          f"the XMP gimbal attitude; factory focal: DewarpData {factory_focal[0]:.1f} px (mean fx, fy), "
          f"CalibratedFocalLength {factory_focal[1]:.1f} px")
    print("| SfM | camera seed | total s | registered | reproj px | position RMS E/N/U m | tag offset m | "
          "RMS E/N/U m, offset removed | rotation to XMP min / median / max deg | focal px |")
    print("|---|---|---|---|---|---|---|---|---|---|", flush=True)
    for row in rows:
        start = f"| {row['label']} | {row['seed'].model} {row['seed'].focal_px:.0f} px | {row['total']:.1f} |"
        if "error" in row:
            print(f"{start} failed: {row['error']} | | | | | | |", flush=True)
            continue
        r, rot = row["report"], row["rotation_deg"]
        offset = r.georegistration["tag_offset"]["along_track_offset_m"]
        print(f"{start} {len(r.registered)}/{r.num_photos} | {r.mean_reprojection_error_px:.2f} | "
              f"{' / '.join(f'{v:.3f}' for v in row['rms_enu'])} | "
              f"{'not observable' if offset is None else f'{offset:+.3f}'} | "
              f"{' / '.join(f'{v:.3f}' for v in r.residual_rms_enu_m_offset_removed)} | "
              f"{rot.min():.2f} / {np.median(rot):.2f} / {rot.max():.2f} | {r.focal_final_px:.1f} |", flush=True)


def yaw_rotation(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def read_odm_cloud(path: Path) -> np.ndarray:
    """``(N, 3)`` float64 points (metres, the file's own frame: UTM 15N for brighton_beach's ``model.laz``) of a
    LAS/LAZ point cloud."""
    las = laspy.read(path)
    return np.column_stack([las.x, las.y, las.z]).astype(np.float64)


@dataclass(frozen=True)
class YawShift:
    """A rigid move about the vertical: a point ``p`` of the moving frame goes to
    ``R(yaw) (p - from_centre) + to_centre + shift`` of the reference frame (metres, radians)."""

    yaw: float
    shift: np.ndarray
    from_centre: np.ndarray
    to_centre: np.ndarray

    def apply(self, points: np.ndarray) -> np.ndarray:
        """``(N, 3)`` moving-frame points in the reference frame."""
        return (points - self.from_centre) @ yaw_rotation(self.yaw).T + self.to_centre + self.shift

    def invert(self, points: np.ndarray) -> np.ndarray:
        """``(N, 3)`` reference-frame points in the moving frame."""
        return (points - self.to_centre - self.shift) @ yaw_rotation(self.yaw) + self.from_centre


def yaw_icp(points: np.ndarray, reference: np.ndarray, iterations: int = 40) -> YawShift:
    """The yaw + translation that puts ``points`` onto ``reference`` (both ``(N, 3)``, metres): a trimmed (80 %)
    ICP started from the centroids (our ENU frame and ODM's UTM grid differ by the meridian convergence and by
    their GPS/datum offsets)."""
    ref_centre, pts_centre = reference.mean(axis=0), points.mean(axis=0)
    ref, pts = reference - ref_centre, points - pts_centre
    tree = cKDTree(ref)
    yaw, shift = 0.0, np.zeros(3)
    for _ in range(iterations):
        moved = pts @ yaw_rotation(yaw).T + shift
        dist, idx = tree.query(moved)
        keep = dist < np.percentile(dist, 80)
        rot2 = umeyama(moved[keep, :2], ref[idx[keep], :2], with_scale=False).rotation
        yaw += np.arctan2(rot2[1, 0], rot2[0, 0])
        rotated = pts @ yaw_rotation(yaw).T
        shift = (ref[idx[keep]] - rotated[keep]).mean(axis=0)
    return YawShift(float(yaw), shift, pts_centre, ref_centre)


def distances_after_yaw_icp(points: np.ndarray, reference: np.ndarray, iterations: int = 40) -> np.ndarray:
    """Nearest-reference distances (m) of ``points`` after :func:`yaw_icp`."""
    fit = yaw_icp(points, reference, iterations)
    return cKDTree(reference - fit.to_centre).query(fit.apply(points) - fit.to_centre)[0]


def bench_dense(photo_dir: Path, reference: np.ndarray, dense_size: int, features: int) -> dict:
    with tempfile.TemporaryDirectory() as scene:
        options = ReconOptions(sfm=SfmOptions(max_image_size=1000, max_num_features=features),
                               dense=DenseOptions(max_image_size=dense_size))
        run = Recon(photo_dir, None, Path(scene), options, log=lambda message: None)
        run.run()
        fused = trimesh.load(Path(scene) / "work" / "fused.ply", process=False).vertices
        mesh = trimesh.load(Path(scene) / "work" / "mesh.ply", process=False)
        realism = scene_photorealism(Path(scene), read_rgb)
        return {"size": dense_size, "seconds": run.seconds, "fused_points": len(fused), "faces": len(mesh.faces),
                "fused": distances_after_yaw_icp(np.asarray(fused), reference),
                "mesh": distances_after_yaw_icp(np.asarray(mesh.vertices), reference),
                "realism": [r.error_percent for r in realism], "covered": [r.covered for r in realism]}


def print_dense_table(rows: list[dict]) -> None:
    print("\n| dense px | undistort s | depth s | fusion s | mesh s | fused pts | mesh faces "
          "| fused vs model.laz median/p90 m | 2.5-D mesh vs model.laz median/p90 m | texture s "
          "| photorealism % median (min-max) | covered % median |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        s = row["seconds"]
        f, m = row["fused"], row["mesh"]
        print(f"| {row['size']} | {s['undistort']:.1f} | {s['depth']:.1f} | {s['fusion']:.1f} | {s['mesh']:.1f} | "
              f"{row['fused_points']} | {row['faces']} | {np.median(f):.2f} / {np.percentile(f, 90):.2f} | "
              f"{np.median(m):.2f} / {np.percentile(m, 90):.2f} | {s['texture']:.1f} | "
              f"{np.median(row['realism']):.2f} ({min(row['realism']):.2f}-{max(row['realism']):.2f}) | "
              f"{100 * np.median(row['covered']):.0f} |")


#: Closed-loop rows: (label, dense px, mesh, texture options or None for vertex colours). SfM runs once.
CLOSED_LOOP_ROWS = (
    ("dense 800, 2.5-D, texel 1 GSD (test)", 800, "2.5d", TextureOptions()),
    ("dense 640", 640, "2.5d", TextureOptions()),
    ("poisson (depth 10)", 800, "poisson", TextureOptions()),
    ("texel 2 GSD", 800, "2.5d", TextureOptions(texel_m=0.18)),
    ("texel 1 GSD, no exposure balancing", 800, "2.5d", TextureOptions(balance_exposure=False)),
    ("vertex colours only", 800, "2.5d", None),
)


def bench_closed_loop() -> list[dict]:
    """The closed-loop flight once, SfM once, then every row of CLOSED_LOOP_ROWS from the stages it shares."""
    world = load_scene(demo_scene_dir("small"))
    rows = []
    with tempfile.TemporaryDirectory() as work:
        work = Path(work)
        flight = fly(world, Orbit(), work)
        first = None
        for label, dense_px, mesh, texture in CLOSED_LOOP_ROWS:
            scene_dir = work / f"scene{len(rows)}"
            if first is not None:
                same_dense = dense_px == CLOSED_LOOP_ROWS[0][1]
                same_mesh = same_dense and mesh == CLOSED_LOOP_ROWS[0][2]
                reuse_stages(first, scene_dir, ("sfm_report.json", "sparse", "stages/sfm.json")
                             + (("dense", "fused.ply", "stages/undistort.json", "stages/depth.json",
                                 "stages/fusion.json") if same_dense else ())
                             + (("mesh.ply", "mesh_decimated.ply", "stages/mesh.json") if same_mesh else ()))
            options = ReconOptions(sfm=SfmOptions(max_image_size=800, max_num_features=4096),
                                   dense=DenseOptions(max_image_size=dense_px), mesh=mesh,
                                   texture=texture is not None, texture_options=texture or TextureOptions())
            run = Recon(flight.photo_dir, flight.geotags_csv, scene_dir, options, log=lambda message: None)
            run.run()
            first = first or scene_dir
            reconstructed = load_scene(scene_dir)
            realism = scene_photorealism(scene_dir, read_rgb, every=2)
            rows.append({"label": label, "seconds": run.seconds,
                         "surface": height_errors(reconstructed, world, INNER_RADIUS_M),
                         "disc": height_errors(reconstructed, world, Orbit().radius_m),
                         "realism": float(np.median([r.error_percent for r in realism]))})
    return rows


def print_closed_loop_table(rows: list[dict]) -> None:
    print("\nclosed loop, 24 photos 800x600 over the small demo world, SfM 800 px once (first row's time); "
          "later rows reuse the stages they share with the first (0 s)")
    print("| options | sfm s | undistort+depth+fusion s | mesh s | texture s | surface median m (r <= 25 m) "
          "| completeness @0.25 m (r <= 25 m / 50 m) | photorealism % median |")
    print("|---|---|---|---|---|---|---|---|")
    for row in rows:
        s = row["seconds"]
        print(f"| {row['label']} | {s['sfm']:.1f} | {s['undistort'] + s['depth'] + s['fusion']:.1f} | "
              f"{s['mesh']:.1f} | {s['texture']:.1f} | {row['surface'].median:.3f} | "
              f"{100 * row['surface'].completeness:.1f} % / {100 * row['disc'].completeness:.1f} % | "
              f"{row['realism']:.2f} |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--sizes", type=int, nargs="+", default=[800, 1600])
    parser.add_argument("--with-3200", action="store_true", help="add the COLMAP default size (slow)")
    parser.add_argument("--features", type=int, default=8192)
    parser.add_argument("--dense-sizes", type=int, nargs="*", default=[640, 1000])
    parser.add_argument("--no-synthetic", action="store_true", help="skip the virtual-flight tables (1b and 3)")
    parser.add_argument("--p4m-only", nargs="?", const="", default=None, metavar="LABEL",
                        help="only table 4 (p4m_rtk before/after), optionally only rows whose label contains LABEL")
    args = parser.parse_args(argv)
    pycolmap.logging.minloglevel = 2
    p4m_dir = args.data / "p4m_rtk" / "images"
    p4m_calibration = read_camera_xmp(p4m_dir / "DJI_0010.JPG").calibration
    p4m_focal = (float(np.mean(p4m_calibration.dewarp[:2])), p4m_calibration.focal_px)
    if args.p4m_only is not None:
        print_p4m_rtk_table(bench_p4m_rtk(p4m_dir, args.sizes[0], args.features, args.p4m_only), args.sizes[0],
                            p4m_focal)
        return 0
    photo_dir = args.data / "brighton_beach" / "images"
    sizes = args.sizes + ([3200] if args.with_3200 else [])
    rows = [bench_size(photo_dir, size, args.features) for size in sizes]
    print(f"brighton_beach, {len(list_photos(photo_dir))} photos 4000x2250, SIFT <= {args.features}, spatial k=12, "
          "incremental + ENU priors, focal fixed at the profile value")
    print_size_table(rows, ["GPS residual RMS E/N/U m"],
                     lambda row: ["/".join(f"{v:.2f}" for v in row["report"].residual_rms_enu_m)])
    if not args.no_synthetic:
        rows, orbit = bench_sizes_virtual(sizes, args.features)
        print(f"\nvirtual flight: {orbit.photos} photos {orbit.width}x{orbit.height} on the closed-loop orbit over the "
              f"small demo world (GPS sigma {orbit.gps_sigma_m} m), SIFT <= {args.features}, default SfM otherwise")
        print_size_table(rows, ["position error median / max m", "rotation error median / max deg", "focal error %"],
                         lambda row: [f"{row['errors'].position_m['median']:.3f} / {row['errors'].position_m['max']:.3f}",
                                      f"{row['errors'].rotation_deg['median']:.3f} / "
                                      f"{row['errors'].rotation_deg['max']:.3f}", f"{row['focal_error_pct']:+.2f}"])
    if args.dense_sizes:
        reference = read_odm_cloud(args.data / "brighton_beach" / "model.laz")
        dense_rows = [bench_dense(photo_dir, reference, size, args.features) for size in args.dense_sizes]
        print_dense_table(dense_rows)
    if not args.no_synthetic:
        print_closed_loop_table(bench_closed_loop())
    print_p4m_rtk_table(bench_p4m_rtk(p4m_dir, args.sizes[0], args.features), args.sizes[0], p4m_focal)
    return 0


if __name__ == "__main__":
    sys.exit(main())
