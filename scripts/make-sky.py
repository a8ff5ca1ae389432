#!/usr/bin/env python3
"""Writes scenes/environment/sky.hdr: a small equirectangular sky for the bundled environment
scene, a blue gradient above the horizon, a dim ground below and a bright sun disc.

Orientation as docs/scene-format.md ("Lights") states it: row 0 looks up (+y); u runs from -z
through +x, +z (the image's centre) and -x. The sun stands 35 degrees above the horizon at
u = 0.3 (mostly towards +x), so shadows fall towards -x.

Other scenes' skies (scripts/make-material-preview.py) import sky() and write_hdr() with their
own parameters.
"""
import math
import os
import sys

WIDTH, HEIGHT = 64, 32
SUN_U, SUN_ELEVATION_DEG, SUN_RADIUS_DEG, SUN_RADIANCE = 0.3, 35.0, 6.0, 60.0


def direction(u, v):
    theta, phi = v * math.pi, 2.0 * math.pi * u
    return (math.sin(theta) * math.sin(phi), math.cos(theta), -math.sin(theta) * math.cos(phi))


def sky(sun_u, sun_elevation_deg, sun_radius_deg, sun_rgb, horizon=(0.9, 0.9, 1.0),
        zenith=(0.25, 0.45, 1.0), ground=(0.25, 0.22, 0.2)):
    """The radiance(u, v) of a sky: a sun disc of radiance sun_rgb, a gradient from the horizon
    to the zenith above, a uniform ground below."""
    sun = direction(sun_u, 0.5 - sun_elevation_deg / 180.0)
    cos_radius = math.cos(math.radians(sun_radius_deg))

    def radiance(u, v):
        d = direction(u, v)
        if sum(a * b for a, b in zip(d, sun)) > cos_radius:
            return tuple(sun_rgb)
        if d[1] < 0.0:
            return tuple(ground)
        t = d[1]  # 0 at the horizon, 1 at the zenith
        return tuple(h + (z - h) * t for h, z in zip(horizon, zenith))

    return radiance


def rgbe(rgb):
    m = max(rgb)
    if m < 1e-32:
        return bytes((0, 0, 0, 0))
    mantissa, exponent = math.frexp(m)
    scale = mantissa * 256.0 / m
    return bytes([int(c * scale) for c in rgb] + [exponent + 128])


def write_hdr(path, width, height, radiance):
    """A flat (not run-length encoded) Radiance HDR of radiance(u, v) at the texel centres."""
    data = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n")
    data += b"-Y %d +X %d\n" % (height, width)
    for y in range(height):
        for x in range(width):
            # Each texel's value at its centre: nearest lookup shows exactly this.
            data += rgbe(radiance((x + 0.5) / width, (y + 0.5) / height))
    with open(path, "wb") as f:
        f.write(data)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(__file__), "..", "scenes", "environment", "sky.hdr")
    sun = (SUN_RADIANCE, SUN_RADIANCE * 0.9, SUN_RADIANCE * 0.75)
    write_hdr(out, WIDTH, HEIGHT, sky(SUN_U, SUN_ELEVATION_DEG, SUN_RADIUS_DEG, sun))


if __name__ == "__main__":
    main()
