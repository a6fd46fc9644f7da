"""Benchmark the demo world: generation time and peak memory, and for each mesh format its size, trimesh load time and texture error.

Prints one table per variant. The chosen format (GLB with an embedded JPEG atlas) is the baseline of the load-time
ratio; the texture error is the mean absolute 8-bit difference between the texture trimesh loads and the lossless
atlas (so lossy compression shows up beside the time it saves).

    .venv/bin/python tools/bench/bench_worlds.py [--variants small default large] [--seed 0]
"""

from __future__ import annotations

import argparse
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

from sim.render.scene import load_scene
from sim.worlds.demo import build_demo_world, encode_glb, generate_world
from sim.worlds.geometry import Part
from sim.worlds.layout import VARIANTS


def _trimesh_of(mesh: Part, atlas: np.ndarray) -> trimesh.Trimesh:
    material = trimesh.visual.material.SimpleMaterial(image=Image.fromarray(atlas))
    visual = trimesh.visual.TextureVisuals(uv=mesh.uv, material=material)
    return trimesh.Trimesh(mesh.vertices, mesh.faces, visual=visual, process=False)


def write_glb_jpeg(mesh: Part, atlas: np.ndarray, folder: Path) -> Path:
    path = folder / "world.glb"
    path.write_bytes(encode_glb(mesh, atlas))
    return path


def write_glb_png(mesh: Part, atlas: np.ndarray, folder: Path) -> Path:
    path = folder / "world_png.glb"
    path.write_bytes(trimesh.exchange.gltf.export_glb(trimesh.Scene(_trimesh_of(mesh, atlas))))
    return path


def write_obj_png(mesh: Part, atlas: np.ndarray, folder: Path) -> Path:
    path = folder / "world.obj"
    _trimesh_of(mesh, atlas).export(path)
    return path


FORMATS = {"GLB + JPEG q95 (chosen)": write_glb_jpeg, "GLB + PNG": write_glb_png, "OBJ + MTL + PNG": write_obj_png}


def _loaded_texture(loaded: trimesh.Trimesh) -> np.ndarray:
    material = loaded.visual.material
    image = material.baseColorTexture if hasattr(material, "baseColorTexture") else material.image
    return np.asarray(image.convert("RGB"), dtype=np.int16)


def bench_variant(variant: str, seed: int) -> None:
    tracemalloc.start()  # numpy reports its buffers to tracemalloc: the peak is the generator's memory
    start = time.perf_counter()
    _, mesh, atlas, _, _ = generate_world(variant, seed)
    generate_s = time.perf_counter() - start
    peak_mb = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    print(f"\nvariant {variant!r}, seed {seed}: {len(mesh.faces):,} triangles, {atlas.shape[1]}x{atlas.shape[0]} atlas,"
          f" generated in {generate_s:.2f} s, peak memory {peak_mb:.0f} MB")
    print(f"{'format':<26}{'write s':>9}{'files MB':>10}{'load s':>8}{'load ratio':>12}{'texture MAE':>13}")
    baseline = None
    for name, write in FORMATS.items():
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            start = time.perf_counter()
            path = write(mesh, atlas, folder)
            write_s = time.perf_counter() - start
            size_mb = sum(p.stat().st_size for p in folder.iterdir()) / 1e6
            start = time.perf_counter()
            loaded = trimesh.load(path, force="mesh")
            texture = _loaded_texture(loaded)
            load_s = time.perf_counter() - start
        baseline = baseline or load_s
        error = float(np.abs(texture - atlas.astype(np.int16)).mean())
        print(f"{name:<26}{write_s:>9.2f}{size_mb:>10.1f}{load_s:>8.2f}{load_s / baseline:>12.2f}{error:>13.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = build_demo_world(tmp, variant, seed)
        start = time.perf_counter()
        load_scene(folder)
        print(f"scene folder -> ray-castable Scene (sim.render.scene.load_scene, embree): {time.perf_counter() - start:.2f} s")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", nargs="+", default=["small", "default"], choices=sorted(VARIANTS))
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    for variant in args.variants:
        bench_variant(variant, args.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
