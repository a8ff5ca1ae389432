#!/usr/bin/env python3
"""Writes the small texture images of scenes/textured/ (PNG, made here so that their source is
this script): tiles.png, an 8-bit sRGB albedo of warm tiles with darker grout, and
roughness.png, an 8-bit gray map (linear) that makes the grout rough and the tiles glossy.

Usage: python3 scripts/make-textures.py scenes/textured
"""
import math
import struct
import sys
import zlib
from pathlib import Path


def write_png(path, width, height, channels, pixel):
    """pixel(x, y) -> tuple of `channels` bytes; row 0 is the image's top."""
    colour_type = {1: 0, 3: 2}[channels]
    rows = bytearray()
    for y in range(height):
        rows.append(0)  # filter: none
        for x in range(width):
            rows.extend(pixel(x, y))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, colour_type, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
    if channels == 1:
        png += chunk(b"gAMA", struct.pack(">I", 100000))  # gamma 1.0: linear values
    png += chunk(b"IDAT", zlib.compress(bytes(rows), 9)) + chunk(b"IEND", b"")
    Path(path).write_bytes(png)


def grout(x, y, size, tiles):
    cell = size // tiles
    return x % cell < 2 or y % cell < 2


def main():
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "scenes/textured")
    size, tiles = 128, 4

    def albedo(x, y):
        if grout(x, y, size, tiles):
            return (70, 66, 60)
        tx, ty = x // (size // tiles), y // (size // tiles)
        shade = 0.85 + 0.15 * math.sin(3.1 * tx + 1.7 * ty)  # each tile a little different
        return tuple(int(min(255, c * shade)) for c in (205, 120, 70))

    def roughness(x, y):
        return (230,) if grout(x, y, size, tiles) else (40,)

    write_png(out / "tiles.png", size, size, 3, albedo)
    write_png(out / "roughness.png", size, size, 1, roughness)


if __name__ == "__main__":
    main()
