#!/usr/bin/env python3
"""Writes the images of scenes/material-preview/ (made here so that their source is this
script), with the sky and PNG writers of make-sky.py and make-textures.py:

- sky.hdr, a 128x64 Radiance HDR studio sky: a pale grey-blue gradient, a neutral ground, and a
  large warm key light (a disc of 11 degrees radius) standing 40 degrees high behind the camera's left
  shoulder, so that every sphere is lit from the front and casts its shadow back and right;
- dimples.png, a 128x64 linear height map of hammered metal (the distance to the nearest of
  scattered points, squared: round dents that meet in ridges), wrapping around in u;
- pillows.png, a 128x64 tangent-space normal map of rounded square pillows, 8 by 4 of them.

Usage: python3 scripts/make-material-preview.py scenes/material-preview
"""
import importlib.util
import math
import sys
from pathlib import Path


def script(name):
    sys.dont_write_bytecode = True  # the scripts folder stays as the repository has it
    spec = importlib.util.spec_from_file_location(name.replace("-", "_"),
                                                  Path(__file__).with_name(name + ".py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


WIDTH, HEIGHT = 128, 64


def hash01(i, j, k):
    """A fixed pseudo-random number in [0, 1) for the integers (i, j, k)."""
    n = (i * 374761393 + j * 668265263 + k * 2147483647) & 0xFFFFFFFF
    n = ((n ^ (n >> 13)) * 1274126177) & 0xFFFFFFFF
    return ((n ^ (n >> 16)) & 0xFFFFFF) / float(1 << 24)


def dimple_height(x, y, cells_x=16, cells_y=8):
    """0 at a dent's centre, growing to its rim; the cells repeat in x so that u wraps."""
    cx, cy = x / WIDTH * cells_x, y / HEIGHT * cells_y
    best = 1e9
    for j in range(int(cy) - 1, int(cy) + 2):
        for i in range(int(cx) - 1, int(cx) + 2):
            ii, jj = i % cells_x, max(0, min(cells_y - 1, j))
            px = i + 0.15 + 0.7 * hash01(ii, jj, 1)
            py = j + 0.15 + 0.7 * hash01(ii, jj, 2)
            best = min(best, (cx - px) ** 2 + (cy - py) ** 2)
    return min(1.0, best)


def pillow_height(u, v, cells_u=8, cells_v=4):
    fu, fv = (u * cells_u) % 1.0, (v * cells_v) % 1.0
    return (1.0 - abs(2 * fu - 1) ** 4) * (1.0 - abs(2 * fv - 1) ** 4)


def pillow_normal(x, y, strength=0.12):
    """The normal map's RGB at texel (x, y): x along +u, y along +v (the image's up), z out."""
    u, v = (x + 0.5) / WIDTH, 1.0 - (y + 0.5) / HEIGHT
    e = 1e-3
    dhdu = (pillow_height(u + e, v) - pillow_height(u - e, v)) / (2 * e)
    dhdv = (pillow_height(u, v + e) - pillow_height(u, v - e)) / (2 * e)
    n = (-strength * dhdu / 8, -strength * dhdv / 4, 1.0)  # per pillow, not per unit of uv
    length = math.sqrt(sum(c * c for c in n))
    return tuple(int(round((c / length * 0.5 + 0.5) * 255)) for c in n)


def main():
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "scenes/material-preview")
    sky, textures = script("make-sky"), script("make-textures")
    studio = sky.sky(sun_u=0.6, sun_elevation_deg=40.0, sun_radius_deg=11.0,
                     sun_rgb=(14.0, 12.6, 11.0), horizon=(0.85, 0.85, 0.85),
                     zenith=(0.35, 0.42, 0.55), ground=(0.18, 0.18, 0.18))
    sky.write_hdr(out / "sky.hdr", WIDTH, HEIGHT, studio)
    textures.write_png(out / "dimples.png", WIDTH, HEIGHT, 1,
                       lambda x, y: (int(round(255 * dimple_height(x + 0.5, y + 0.5))),))
    textures.write_png(out / "pillows.png", WIDTH, HEIGHT, 3, pillow_normal)


if __name__ == "__main__":
    main()
