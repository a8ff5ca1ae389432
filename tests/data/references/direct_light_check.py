"""Direct light on scenes/cornell-blocks against its exact value: which renderer is right.

    python3 tests/data/references/direct_light_check.py A.exr [B.exr ...]

Each image is a 64x64 render of scenes/cornell-blocks with max_depth 1 (direct light only; for
Cycles, max_bounces 0), for example:

    rayfarm render scenes/cornell-blocks/scene.json --max-depth 1 --integrator nee --spp 4096 -o ours.exr
    blender -b --factory-startup --python scripts/blender_reference.py -- S1.json cycles.exr --spp 8192
    blender -b --factory-startup --python scripts/blender_reference.py -- S1.json cycles-bsdf.exr \
        --spp 8192 --no-light-sampling
    (S1.json: the scene with "max_depth": 1)

For every pixel whose 8x8 sub-pixel grid of camera rays lands on one wall (floor, back, red, green)
and from which the quad light is unoccluded, the exact pixel value is the box-filtered
albedo / pi x L x (Lambert's polygon formula for the irradiance of a unit-radiance quad,
1/2 sum_i theta_i n . unit(v_i x v_i+1)). Prints image / exact per wall and band of 8 rows (red
channel). Reads scanline EXR files (no compression, ZIPS or ZIP; half or float channels) itself:
plain Python 3, no Blender, no packages.
"""
import json
import math
import os
import struct
import sys
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "..", "..", "..", "scenes", "cornell-blocks", "scene.json")


def read_exr_channel(path, want="R"):
    """One channel of a scanline EXR as rows of floats, top row first."""
    data = open(path, "rb").read()
    if struct.unpack_from("<I", data, 0)[0] != 20000630:
        raise ValueError(f"{path}: not an OpenEXR file")
    pos, attrs = 8, {}
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        tend = data.index(b"\0", end + 1)
        size = struct.unpack_from("<i", data, tend + 1)[0]
        attrs[name] = data[tend + 5:tend + 5 + size]
        pos = tend + 5 + size
    pos += 1
    channels, c = [], 0
    raw = attrs["channels"]
    while raw[c] != 0:
        end = raw.index(b"\0", c)
        channels.append((raw[c:end].decode(), struct.unpack_from("<i", raw, end + 1)[0]))
        c = end + 1 + 16
    compression = attrs["compression"][0]
    if compression not in (0, 2, 3):
        raise ValueError(f"{path}: compression {compression} not supported (none, ZIPS, ZIP only)")
    x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    lines_per_chunk = {0: 1, 2: 1, 3: 16}[compression]
    chunks = (h + lines_per_chunk - 1) // lines_per_chunk
    offsets = struct.unpack_from(f"<{chunks}Q", data, pos)
    sizes = {1: 2, 2: 4}  # HALF, FLOAT
    rows = {}
    for off in offsets:
        y, size = struct.unpack_from("<2i", data, off)
        block = data[off + 8:off + 8 + size]
        n_lines = min(lines_per_chunk, y1 + 1 - y)
        expected = n_lines * w * sum(sizes[t] for _, t in channels)
        if compression and size < expected:
            t = bytearray(zlib.decompress(block))
            for i in range(1, len(t)):
                t[i] = (t[i - 1] + t[i] - 128) & 0xFF
            half = (len(t) + 1) // 2
            out = bytearray(len(t))
            out[0::2], out[1::2] = t[:half], t[half:]
            block = bytes(out)
        p = 0
        for line in range(n_lines):
            for name, ctype in channels:  # channels are stored in alphabetical order
                n = w * sizes[ctype]
                if name == want:
                    fmt = "<%de" % w if ctype == 1 else "<%df" % w
                    rows[y + line - y0] = list(struct.unpack_from(fmt, block, p))
                p += n
    return [rows[i] for i in range(h)]


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def unit(a):
    n = math.sqrt(dot(a, a))
    return (a[0] / n, a[1] / n, a[2] / n)


def hit_triangle(o, d, tri):
    v0, v1, v2 = tri
    e1, e2 = sub(v1, v0), sub(v2, v0)
    p = cross(d, e2)
    det = dot(e1, p)
    if abs(det) < 1e-12:
        return None
    s = sub(o, v0)
    u = dot(s, p) / det
    if u < 0 or u > 1:
        return None
    q = cross(s, e1)
    v = dot(d, q) / det
    if v < 0 or u + v > 1:
        return None
    t = dot(e2, q) / det
    return t if t > 1e-6 else None


def main():
    with open(SCENE, encoding="utf-8") as f:
        scene = json.load(f)
    cam = scene["camera"]
    w, h = scene["film"]["width"], scene["film"]["height"]
    tan_half = math.tan(math.radians(cam["fov_y"]) / 2)
    eye = tuple(cam["eye"])
    blocks = [tuple(tuple(v) for v in s["vertices"]) for s in scene["shapes"] if s["type"] == "triangle"]
    lamp = next(s for s in scene["shapes"] if s["material"] == "light")
    c, e1, e2 = lamp["corner"], lamp["edge1"], lamp["edge2"]
    light = [tuple(c), tuple(map(sum, zip(c, e1))), tuple(map(sum, zip(c, e1, e2))), tuple(map(sum, zip(c, e2)))]
    radiance = scene["materials"]["light"]["emission"][0]
    albedo = {m: scene["materials"][m]["albedo"][0] for m in ("white", "red", "green")}
    # The room's walls as axis-aligned planes: name, axis, position, normal, albedo (red channel).
    walls = [("floor", 1, 0.0, (0, 1, 0), albedo["white"]), ("ceiling", 1, 548.8, (0, -1, 0), 0.0),
             ("back", 2, 559.2, (0, 0, -1), albedo["white"]), ("green", 0, 0.0, (1, 0, 0), albedo["green"]),
             ("red", 0, 556.0, (-1, 0, 0), albedo["red"])]
    forward = unit(sub(cam["look_at"], eye))
    right = unit(cross(forward, cam["up"]))
    up = cross(right, forward)

    def trace(d):
        best, what = 1e30, None
        for name, axis, pos, n, alb in walls:
            if abs(d[axis]) > 1e-12:
                t = (pos - eye[axis]) / d[axis]
                if 1e-6 < t < best:
                    best, what = t, (name, n, alb)
        for tri in blocks:
            t = hit_triangle(eye, d, tri)
            if t is not None and t < best:
                best, what = t, None
        y = light[0][1]
        t = (y - eye[1]) / d[1] if d[1] else -1
        if 1e-6 < t < best:
            p = [eye[i] + t * d[i] for i in range(3)]
            if light[0][0] <= p[0] <= light[1][0] and light[0][2] <= p[2] <= light[2][2]:
                best, what = t, None
        return best, what

    def irradiance(x, n):
        s = 0.0
        for i in range(4):
            a, b = unit(sub(light[i], x)), unit(sub(light[(i + 1) % 4], x))
            s += math.acos(max(-1.0, min(1.0, dot(a, b)))) * dot(n, unit(cross(a, b)))
        return abs(s) / 2

    def occluded(x):
        targets = light + [tuple(sum(p[i] for p in light) / 4 for i in range(3))]
        return any(hit_triangle(x, sub(q, x), tri) is not None and hit_triangle(x, sub(q, x), tri) < 1 - 1e-6
                   for q in targets for tri in blocks)

    exact = {}
    grid = 8
    for py in range(h):
        for px in range(w):
            total, wall, ok = 0.0, None, True
            points = []
            for j in range(grid):
                for i in range(grid):
                    fx, fy = px + (i + 0.5) / grid, py + (j + 0.5) / grid
                    sx = (2 * fx / w - 1) * tan_half * (w / h)
                    sy = (1 - 2 * fy / h) * tan_half
                    d = unit(tuple(forward[k] + right[k] * sx + up[k] * sy for k in range(3)))
                    t, what = trace(d)
                    if what is None or what[0] == "ceiling" or (wall and wall != what[0]):
                        ok = False
                        break
                    wall = what[0]
                    x = tuple(eye[k] + t * d[k] for k in range(3))
                    points.append(x)
                    # The light must be in front of the receiver (walls: always) and unoccluded.
                    total += what[2] / math.pi * radiance * irradiance(x, what[1])
                if not ok:
                    break
            if ok and not any(occluded(x) for x in (points[0], points[-1], points[len(points) // 2])):
                exact[(px, py)] = (total / (grid * grid), wall)

    for path in sys.argv[1:]:
        red = read_exr_channel(path, "R")
        bands = {}
        for (px, py), (value, wall) in exact.items():
            got = red[py][px]
            b = bands.setdefault((wall, py // 8), [0, 0.0])
            b[0] += 1
            b[1] += got / value
        print(f"\n{path}: image / exact, red channel, pixels wholly on one unoccluded wall")
        for (wall, band), (n, s) in sorted(bands.items()):
            print(f"  {wall:6} rows {band * 8:2}-{band * 8 + 7:2}: {n:3} px  {s / n:.4f}")


main()
