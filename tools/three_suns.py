"""One photo pose of two twins under several suns, in one labelled picture: the relighting before and after.

    .venv/bin/python tools/three_suns.py --before KEPT_LIGHT_SCENE --after DELIT_SCENE --photo 45
        --out docs/three_suns.png [--width 256] [--crop LEFT,TOP,RIGHT,BOTTOM]
        [--lights morning=90,25,8,noon=180,60,8,evening=270,20,8,overcast=overcast] [--work DIR]

``--before`` is a twin whose texture keeps its capture day's light (``aerostereo-recon --keep-capture-light``), so
every sun it is lit by lies beside the shadows baked into it; ``--after`` the same flight reconstructed with the
light divided out (the default), whose albedo is lit by the new sun alone. Each twin is rendered by the render CLI
at the pose of its own photo ``--photo`` (an index into cameras.json, from 0; ``--mode replay``: the reconstruction's ``cameras.json``, that
photo's lens scaled to ``--width``) under every light of ``--lights`` (``--lighting-variants``: one process per twin,
the scene loaded once; each SUN as ``--sun`` takes it). The left images, cut to ``--crop`` (fractions of the image:
a building and its shadows), go into a grid, a row per twin and a column per light, written to ``--out`` as an 8-bit
palette PNG (small enough for the docs). The datasets are rendered into
``--work`` (default: a temporary folder, removed afterwards).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from PIL import Image, ImageDraw, ImageFont  # noqa: E402

from sim.cli import main as render_main  # noqa: E402
from sim.cli.light import lighting_variants_value  # noqa: E402
from sim.run.variants import LightingVariant  # noqa: E402

DEFAULT_LIGHTS = "morning=90,25,8,noon=180,60,8,evening=270,20,8,overcast=overcast"
#: Row labels of the two twins.
TWINS = (("before", "before: the texture as photographed (--keep-capture-light), relit"),
         ("after", "after: the albedo (the capture light divided out), relit"))
#: Height of the label strips above each row and each column, pixels.
LABEL_PX = 18


def render_photo_pose(scene: Path, photo: int, width: int, lights: str, out: Path) -> None:
    """Render the pose of photo number ``photo`` of ``scene``'s cameras.json under each of ``lights`` (NAME=SUN,...)
    into ``out/NAME`` with the render CLI: frames 0..photo of the replay, of which only the last (shard photo of
    photo + 1)."""
    argv = ["--scene", str(scene), "--out", str(out), "--mode", "replay", "--frames", str(photo + 1),
            "--shard", f"{photo}/{photo + 1}", "--width", str(width), "--lighting-variants", lights,
            "--formats", "depth_exr", "--quiet"]
    code = render_main(argv)
    if code != 0:
        raise SystemExit(f"aerostereo-render {' '.join(argv)} failed with exit code {code}")


def crop_value(text: str) -> tuple[float, float, float, float]:
    """``--crop LEFT,TOP,RIGHT,BOTTOM``: fractions of the image's width and height, 0 <= LEFT < RIGHT <= 1 and
    0 <= TOP < BOTTOM <= 1."""
    try:
        left, top, right, bottom = (float(value) for value in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LEFT,TOP,RIGHT,BOTTOM fractions, got {text!r}") from None
    if not (0 <= left < right <= 1 and 0 <= top < bottom <= 1):
        raise argparse.ArgumentTypeError(f"expected 0 <= LEFT < RIGHT <= 1 and 0 <= TOP < BOTTOM <= 1, got {text!r}")
    return left, top, right, bottom


def left_image(dataset: Path, photo: int, crop: tuple[float, float, float, float]) -> Image.Image:
    """The left camera's image of frame ``photo`` of a rendered dataset (KITTI layout), cut to ``crop`` (fractions
    LEFT, TOP, RIGHT, BOTTOM of its width and height)."""
    image = Image.open(dataset / "sequences" / "00" / "image_2" / f"{photo:06d}.png").convert("RGB")
    scale = (image.width, image.height) * 2
    return image.crop(tuple(round(fraction * size) for fraction, size in zip(crop, scale)))


def label(draw: ImageDraw.ImageDraw, xy: tuple[int, int], text: str, font) -> None:
    """White ``text`` at ``xy`` (top left, pixels)."""
    draw.text((xy[0] + 4, xy[1] + 3), text, fill=(255, 255, 255), font=font)


def compose(rows: list[tuple[str, list[Image.Image]]], columns: list[str]) -> Image.Image:
    """A grid of equally sized tiles on dark grey: ``columns`` labels on top, each row's label in a strip above it."""
    width, height = rows[0][1][0].size
    grid = Image.new("RGB", (width * len(columns), LABEL_PX + len(rows) * (LABEL_PX + height)), (40, 40, 40))
    draw, font = ImageDraw.Draw(grid), ImageFont.load_default()
    for column, text in enumerate(columns):
        label(draw, (column * width, 0), text, font)
    for row, (text, tiles) in enumerate(rows):
        top = LABEL_PX + row * (LABEL_PX + height)
        label(draw, (0, top), text, font)
        for column, tile in enumerate(tiles):
            grid.paste(tile, (column * width, top + LABEL_PX))
    return grid


def column_label(variant: LightingVariant) -> str:
    """E.g. ``morning: sun az 90 el 25``, or ``overcast: sky only``."""
    sun = variant.sun
    if sun.form == "fixed":
        return f"{variant.name}: sun az {sun.azimuth_deg:g} el {sun.elevation_deg:g}"
    return f"{variant.name}: {'sky only' if sun.form == 'overcast' else sun.text}"


def three_suns(before: Path, after: Path, photo: int, width: int, lights: str, work: Path,
               crop: tuple[float, float, float, float] = (0.0, 0.0, 1.0, 1.0)) -> Image.Image:
    """The labelled grid of the pose of photo ``photo`` of both twins under each of ``lights``, each image cut to
    ``crop``."""
    variants = lighting_variants_value(lights)
    rows = []
    for (name, text), scene in zip(TWINS, (before, after)):
        render_photo_pose(scene, photo, width, lights, work / name)
        rows.append((text, [left_image(work / name / variant.name, photo, crop) for variant in variants]))
    return compose(rows, [column_label(variant) for variant in variants])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", type=Path, required=True, help="twin that kept its capture light")
    parser.add_argument("--after", type=Path, required=True, help="the same twin with the light divided out")
    parser.add_argument("--photo", type=int, default=45, help="the photo whose pose is rendered: its index in cameras.json, from 0")
    parser.add_argument("--width", type=int, default=256, help="width of the rendered images, pixels")
    parser.add_argument("--crop", type=crop_value, default=(0.0, 0.0, 1.0, 1.0),
                        help="part of each image shown: LEFT,TOP,RIGHT,BOTTOM fractions (default: 0,0,1,1, all)")
    parser.add_argument("--lights", default=DEFAULT_LIGHTS, help="NAME=SUN,... as --lighting-variants takes them")
    parser.add_argument("--out", type=Path, required=True, help="the picture (PNG)")
    parser.add_argument("--work", type=Path, help="folder for the rendered datasets (default: temporary)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as temporary:
        grid = three_suns(args.before, args.after, args.photo, args.width, args.lights, args.work or Path(temporary),
                          args.crop)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    grid.quantize(256, dither=Image.Dither.NONE).save(args.out, optimize=True)
    print(f"{args.out}: {grid.width}x{grid.height} px, {args.out.stat().st_size // 1024} KB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
