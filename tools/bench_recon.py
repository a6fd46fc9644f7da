"""Recon knobs against time and error on the real DJI set (brighton_beach, 18 photos, EXIF GPS priors).

    /work/venv/bin/python tools/bench_recon.py [--sizes 800 1600] [--with-3200] [--dense-sizes 640 1000]

Table 1, SfM image size: time per stage, registered photos, 3-D points, mean reprojection error,
camera-centre residual RMS against EXIF GPS (east/north/up), time ratio to the first row. There is no
ground truth for the poses: the GPS residual is bounded by the GPS's own noise.
Table 2, dense image size (whole pipeline, SfM at 1000 px): dense/mesh stage times and the distance of the
fused cloud and of the 2.5-D mesh vertices to ODM's reference cloud ``model.laz`` (UTM 15N), after a
yaw + translation ICP (our ENU frame and ODM's UTM grid differ by the meridian convergence, ~0.7 deg here,
and by their GPS/datum offsets).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import laspy  # noqa: E402
import numpy as np  # noqa: E402
import pycolmap  # noqa: E402
import trimesh  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402

from recon.dense import DenseOptions  # noqa: E402
from recon.pipeline import Recon, ReconOptions  # noqa: E402

from recon.priors import focal_seed, list_photos, priors_from_exif  # noqa: E402
from recon.sfm import SfmOptions, run_sfm  # noqa: E402

DEFAULT_DATA = Path(os.environ.get("AEROSTEREO_SHARED_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


def bench_size(photo_dir: Path, size: int, features: int) -> dict:
    names = list_photos(photo_dir)
    priors = priors_from_exif(photo_dir, names)
    seed = focal_seed(photo_dir / names[0])
    with tempfile.TemporaryDirectory() as work:
        t0 = time.perf_counter()
        _, report = run_sfm(photo_dir, names, priors, seed, Path(work),
                            SfmOptions(max_image_size=size, max_num_features=features))
        total = time.perf_counter() - t0
    return {"size": size, "total": total, "report": report}


def yaw_rotation(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def distances_after_yaw_icp(points: np.ndarray, reference: np.ndarray, iterations: int = 40) -> np.ndarray:
    """Nearest-reference distances (m) of ``points`` after a trimmed (80 %) yaw + translation ICP,
    started from the centroids."""
    ref = reference - reference.mean(axis=0)
    pts = points - points.mean(axis=0)
    tree = cKDTree(ref)
    yaw, shift = 0.0, np.zeros(3)
    for _ in range(iterations):
        moved = pts @ yaw_rotation(yaw).T + shift
        dist, idx = tree.query(moved)
        keep = dist < np.percentile(dist, 80)
        a = moved[keep, :2] - moved[keep, :2].mean(axis=0)
        b = ref[idx[keep], :2] - ref[idx[keep], :2].mean(axis=0)
        u, _, vt = np.linalg.svd(a.T @ b)
        rot2 = vt.T @ np.diag([1.0, np.sign(np.linalg.det(vt.T @ u.T))]) @ u.T
        yaw += np.arctan2(rot2[1, 0], rot2[0, 0])
        rotated = pts @ yaw_rotation(yaw).T
        shift = (ref[idx[keep]] - rotated[keep]).mean(axis=0)
    return tree.query(pts @ yaw_rotation(yaw).T + shift)[0]


def bench_dense(photo_dir: Path, reference: np.ndarray, dense_size: int, features: int) -> dict:
    with tempfile.TemporaryDirectory() as scene:
        options = ReconOptions(sfm=SfmOptions(max_image_size=1000, max_num_features=features),
                               dense=DenseOptions(max_image_size=dense_size))
        run = Recon(photo_dir, None, Path(scene), options, log=lambda message: None)
        run.run()
        fused = trimesh.load(Path(scene) / "work" / "fused.ply", process=False).vertices
        mesh = trimesh.load(Path(scene) / "work" / "mesh.ply", process=False)
        return {"size": dense_size, "seconds": run.seconds, "fused_points": len(fused), "faces": len(mesh.faces),
                "fused": distances_after_yaw_icp(np.asarray(fused), reference),
                "mesh": distances_after_yaw_icp(np.asarray(mesh.vertices), reference)}


def print_dense_table(rows: list[dict]) -> None:
    print("\n| dense px | undistort s | depth s | fusion s | mesh s | fused pts | mesh faces "
          "| fused vs model.laz median/p90 m | 2.5-D mesh vs model.laz median/p90 m |")
    print("|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        s = row["seconds"]
        f, m = row["fused"], row["mesh"]
        print(f"| {row['size']} | {s['undistort']:.1f} | {s['depth']:.1f} | {s['fusion']:.1f} | {s['mesh']:.1f} | "
              f"{row['fused_points']} | {row['faces']} | {np.median(f):.2f} / {np.percentile(f, 90):.2f} | "
              f"{np.median(m):.2f} / {np.percentile(m, 90):.2f} |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--sizes", type=int, nargs="+", default=[800, 1600])
    parser.add_argument("--with-3200", action="store_true", help="add the COLMAP default size (slow)")
    parser.add_argument("--features", type=int, default=8192)
    parser.add_argument("--dense-sizes", type=int, nargs="*", default=[640, 1000])
    args = parser.parse_args(argv)
    pycolmap.logging.minloglevel = 2
    photo_dir = args.data / "brighton_beach" / "images"
    sizes = args.sizes + ([3200] if args.with_3200 else [])
    rows = [bench_size(photo_dir, size, args.features) for size in sizes]
    base = rows[0]["total"]
    print(f"brighton_beach, {len(list_photos(photo_dir))} photos 4000x2250, SIFT <= {args.features}, spatial k=12, "
          "incremental + ENU priors, focal fixed at the profile value")
    print("| max px | extract s | match s | map s | total s | x first | registered | 3-D pts | reproj px "
          "| GPS residual RMS E/N/U m |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        r, s = row["report"], row["report"].seconds
        rms = "/".join(f"{v:.2f}" for v in r.residual_rms_enu_m)
        print(f"| {row['size']} | {s['extract']:.1f} | {s['match']:.1f} | {s['map']:.1f} | {row['total']:.1f} | "
              f"{row['total'] / base:.2f} | {len(r.registered)}/{r.num_photos} | {r.num_points3d} | "
              f"{r.mean_reprojection_error_px:.2f} | {rms} |")
    if args.dense_sizes:
        las = laspy.read(args.data / "brighton_beach" / "model.laz")
        reference = np.column_stack([las.x, las.y, las.z]).astype(np.float64)
        print_dense_table([bench_dense(photo_dir, reference, size, args.features) for size in args.dense_sizes])
    return 0


if __name__ == "__main__":
    sys.exit(main())
