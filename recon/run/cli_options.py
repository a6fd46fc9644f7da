"""The reconstruction's command-line options, shared by ``aerostereo-recon`` (one scene, recon/cli.py) and
``aerostereo-recon area`` (each piece of an area, recon/area/cli.py): the program's name, the options and their
argument types, and the :class:`~recon.run.pipeline.ReconOptions` they make.
"""

from __future__ import annotations

import argparse
import re

from recon.surface.dense import DenseOptions
from recon.run.pipeline import MESHES, STANDING, TEXTURES, WATER, ReconOptions
from recon.sfm.options import SfmOptions
from recon.appearance.atlas import AtlasOptions
from recon.appearance.texture import TextureOptions

PROGRAM = "aerostereo-recon"


def positive_int(text: str) -> int:
    value = int(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


POISSON_DEPTHS = range(6, 13)
"""``--poisson-depth`` values: the octree's cell is the surface's extent / 2^depth (10 on the default orbit's 130 m:
0.13 m); every level more takes about 2-4x the time and memory (brighton_beach: 16 s at 9, 37 s at 10)."""


def poisson_depth(text: str) -> int:
    """``--poisson-depth``: an octree depth in :data:`POISSON_DEPTHS`."""
    value = int(text) if text.strip().lstrip("+-").isdigit() else None
    if value not in POISSON_DEPTHS:
        raise argparse.ArgumentTypeError(f"expected an octree depth from {POISSON_DEPTHS.start} to "
                                         f"{POISSON_DEPTHS.stop - 1}, got {text}")
    return value


def hold_out_count(text: str) -> int:
    """``--hold-out``: 0 (off) or K >= 2; K = 1 is refused by :class:`ReconOptions` with its reason."""
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 (off) or an every-K-th count >= 2, got {text}")
    return value


def add_recon_options(parser: argparse.ArgumentParser) -> None:
    """The reconstruction's options, shared by a single scene and each piece of an area."""
    parser.add_argument("--image-size", type=positive_int, default=SfmOptions.max_image_size,
                        help="SfM max image side, px (default %(default)s)")
    parser.add_argument("--max-features", type=positive_int, default=8192, help="SIFT features per photo")
    parser.add_argument("--dense-size", type=positive_int, default=DenseOptions.max_image_size,
                        help="depth-map max image side, px (default %(default)s)")
    parser.add_argument("--depth-spacing", type=float, default=DenseOptions.view_spacing_deg,
                        help="depth maps only for photos at least this many degrees apart seen from the scene "
                             "(default %(default)s; 0: every photo)")
    parser.add_argument("--mesh", choices=MESHES, default=ReconOptions.mesh,
                        help="3d: Poisson surface of the observed area (walls, tree crowns); 2.5d: height field; "
                             "poisson: Poisson of the whole cloud, uncropped (default %(default)s)")
    parser.add_argument("--grid", type=float, help="height-field cell size, m (default: 2 ground pixels)")
    parser.add_argument("--poisson-depth", type=poisson_depth, default=ReconOptions.poisson_depth,
                        help="octree depth of the Poisson surface (--mesh 3d, poisson): its cell is the surface's "
                             "extent / 2^depth; one less is about 2-4x faster and coarser (default %(default)s)")
    parser.add_argument("--water", choices=WATER, default=ReconOptions.water,
                        help="plane: open water the fused points show (plain, level, lower than its shore) becomes a "
                             "plane at its level, marked proxy in the face provenance; none: the raw surface "
                             "(default %(default)s)")
    parser.add_argument("--standing", choices=STANDING, default=ReconOptions.standing,
                        help="heightfield: where the fused points' height field stands more than 1 m over the 3-D "
                             "surface (a shelter, a young tree Poisson smoothed away), its surface is added there; "
                             "none: the 3-D surface alone (--mesh 3d; default %(default)s)")
    parser.add_argument("--workers", type=int, default=-1, help="threads (-1: all cores)")
    parser.add_argument("--every", type=positive_int, default=None,
                        help="only every k-th photo enters mapping, the rest are registered into its model "
                             "(default: from the photo spacing, about 5 deg apart seen from the flight height)")
    parser.add_argument("--neighbors", type=positive_int, default=12, help="spatial matching: nearest photos")
    parser.add_argument("--sequential", type=int, default=0, help="also match each photo with the next N (0: off)")
    parser.add_argument("--mapper", choices=("incremental", "global"), default="incremental",
                        help="incremental or global SfM mapping")
    parser.add_argument("--focal", choices=("auto", "fixed", "refine"), default="auto",
                        help="focal length: keep the seeded one (fixed), let bundle adjustment move it (refine), or "
                             "refine it only when the viewing directions spread widely, as in an oblique orbit (auto)")
    parser.add_argument("--decimate-error", type=float, default=0.02, help="decimation error bound, m (0: off)")
    parser.add_argument("--texture", choices=TEXTURES, default=ReconOptions.texture,
                        help="atlas: each face from its best photo; ortho: a true orthophoto (for --mesh 2.5d); "
                             "none: vertex colours only (default %(default)s)")
    parser.add_argument("--texel", type=float, help="texel size, m (default: one pixel of the photos on the surface)")
    parser.add_argument("--capture-sun", type=sun_direction, metavar="AZ,EL",
                        help="the sun every photo was taken under, azimuth and elevation in degrees (default: from "
                             "each photo's UTC time in the geotags, over the scene's origin)")
    parser.add_argument("--capture-utc-offset", type=utc_offset, metavar="+HH:MM",
                        help="the time zone of the photos' EXIF clocks where they did not write it, e.g. +01:00 "
                             "(a negative one as --capture-utc-offset=-05:00; default: the UTC offset their shadows on "
                             "the twin show, if clear; else the texture keeps its light)")
    parser.add_argument("--capture-sun-sky-ratio", type=sun_sky_ratio, metavar="R[,G,B]",
                        help="the capture light's sun/sky ratio where it was measured, one value or one per channel: "
                             "a level grey card photographed in the sun and in the shade of a small object under the "
                             "open sky gives (sun / shade - 1) / sin(sun elevation) (default: fitted from the "
                             "texture's shadow edges)")
    parser.add_argument("--keep-capture-light", action="store_true",
                        help="leave the capture day's light in the atlas (by default photos with a UTC time have it "
                             "divided out: the texture is the albedo and capture_light.png the light, so the twin "
                             "can be lit by any sun)")
    parser.add_argument("--hold-out", type=hold_out_count, default=0, metavar="K",
                        help="register every photo but leave every K-th (name order, K >= 2) out of depth maps, "
                             "fusion and texture, to measure photorealism on photos the texture never saw "
                             "(cameras.json marks them held_out; 0: off)")
    parser.add_argument("--verbose", action="store_true", help="show COLMAP's own log")


def sun_direction(text: str) -> tuple[float, float]:
    """``--capture-sun AZ,EL``: degrees, the azimuth in [-360, 360] (clockwise from north; beyond a turn either way
    a float's sine and cosine are noise, 1e308 deg names no direction) and the elevation in (0, 90]."""
    parts = text.split(",")
    try:
        azimuth, elevation = (float(part) for part in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected AZ,EL in degrees (e.g. 150,50), got {text!r}") from None
    if not (-360 <= azimuth <= 360 and 0 < elevation <= 90):  # also refuses NaN and infinities
        raise argparse.ArgumentTypeError(f"expected an azimuth in [-360, 360] and an elevation in (0, 90] degrees, "
                                         f"got {text!r}")
    return azimuth, elevation


def sun_sky_ratio(text: str) -> tuple[float, float, float]:
    """``--capture-sun-sky-ratio R[,G,B]``: the sun's irradiance over the sky's, one positive value for every channel
    or one per channel."""
    try:
        values = tuple(float(part) for part in text.split(","))
    except ValueError:
        values = ()
    if len(values) not in (1, 3) or not all(0 < value < 1000 for value in values):  # also refuses NaN
        raise argparse.ArgumentTypeError(f"expected one sun/sky ratio or three (R,G,B), each above 0 and below 1000 "
                                         f"(e.g. 3.3), got {text!r}")
    return values * 3 if len(values) == 1 else values


def utc_offset(text: str) -> float:
    """``--capture-utc-offset +HH:MM``: hours east of UTC, in [-14, +14]."""
    match = re.fullmatch(r"([+-])(\d{2}):([0-5]\d)", text.strip())
    hours = None if match is None else (int(match[2]) + int(match[3]) / 60.0) * (1 if match[1] == "+" else -1)
    if hours is None or abs(hours) > 14:
        raise argparse.ArgumentTypeError(f"expected a UTC offset +HH:MM in [-14:00, +14:00] (e.g. -05:00), got {text!r}")
    return hours


def recon_options(args: argparse.Namespace) -> ReconOptions:
    """:class:`ReconOptions` from the options of :func:`add_recon_options`."""
    return ReconOptions(
        sfm=SfmOptions(max_image_size=args.image_size, max_num_features=args.max_features,
                       spatial_neighbors=args.neighbors, sequential_overlap=args.sequential, every_kth=args.every,
                       mapper=args.mapper, focal=args.focal, num_threads=args.workers),
        dense=DenseOptions(max_image_size=args.dense_size, view_spacing_deg=args.depth_spacing,
                           num_threads=args.workers),
        mesh=args.mesh, grid_m=args.grid, poisson_depth=args.poisson_depth, decimate_error_m=args.decimate_error,
        water=args.water, standing=args.standing, texture=args.texture, texture_options=TextureOptions(texel_m=args.texel),
        atlas_options=AtlasOptions(texel_m=args.texel), hold_out=args.hold_out,
        delight=not args.keep_capture_light, capture_sun=args.capture_sun,
        capture_sun_sky_ratio=args.capture_sun_sky_ratio,
        capture_utc_offset_h=args.capture_utc_offset,
    )
