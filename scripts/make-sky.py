#!/usr/bin/env python3
"""Writes scenes/environment/sky.hdr: a small equirectangular sky for the bundled environment
scene, a blue gradient above the horizon, a dim ground below and a bright sun disc.

Orientation as docs/scene-format.md ("Lights") states it: row 0 looks up (+y); u runs from -z
through +x, +z (the image's centre) and -x. The sun stands 35 degrees above the horizon at
u = 0.3 (mostly towards +x), so shadows fall towards -x.
"""
import math
import os
import sys

WIDTH, HEIGHT = 64, 32
SUN_U, SUN_ELEVATION_DEG, SUN_RADIUS_DEG, SUN_RADIANCE = 0.3, 35.0, 6.0, 60.0


def direction(u, v):
    theta, phi = v * math.pi, 2.0 * math.pi * u
    return (math.sin(theta) * math.sin(phi), math.cos(theta), -math.sin(theta) * math.cos(phi))


def radiance(u, v):
    d = direction(u, v)
    sun = direction(SUN_U, 0.5 - SUN_ELEVATION_DEG / 180.0)
    cos_sun = sum(a * b for a, b in zip(d, sun))
    if cos_sun > math.cos(math.radians(SUN_RADIUS_DEG)):
        return (SUN_RADIANCE, SUN_RADIANCE * 0.9, SUN_RADIANCE * 0.75)
    if d[1] < 0.0:
        return (0.25, 0.22, 0.2)
    t = d[1]  # 0 at the horizon, 1 at the zenith
    horizon, zenith = (0.9, 0.9, 1.0), (0.25, 0.45, 1.0)
    return tuple(h + (z - h) * t for h, z in zip(horizon, zenith))


def rgbe(rgb):
    m = max(rgb)
    if m < 1e-32:
        return bytes((0, 0, 0, 0))
    mantissa, exponent = math.frexp(m)
    scale = mantissa * 256.0 / m
    return bytes([int(c * scale) for c in rgb] + [exponent + 128])


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(__file__), "..", "scenes", "environment", "sky.hdr")
    data = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n")
    data += b"-Y %d +X %d\n" % (HEIGHT, WIDTH)
    for y in range(HEIGHT):
        for x in range(WIDTH):
            # Each texel's value at its centre: nearest lookup shows exactly this.
            data += rgbe(radiance((x + 0.5) / WIDTH, (y + 0.5) / HEIGHT))
    with open(out, "wb") as f:
        f.write(data)


if __name__ == "__main__":
    main()
