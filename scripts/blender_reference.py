"""Renders a rayfarm scene with Blender Cycles: an independent reference image for tests.

    blender -b --factory-startup --python scripts/blender_reference.py -- \
        SCENE.json OUT.exr --spp N [--seeds K] [--seed S] [--threads T] [--source-name NAME]
        [--res WxH] [--approximate] [--ladder SPP,SPP,... instead of --spp]

Reads our scene JSON (docs/scene-format.md) and builds the same scene in Cycles:

  * quads, triangles and OBJ meshes (v and f statements; faces fanned around their first corner,
    as our loader does) become meshes with flat faces and the same winding;
  * diffuse materials become a Diffuse BSDF (roughness 0: Lambert) of colour `albedo`; an emissive
    material adds an Emission shader of strength 1 and colour `emission` (for a material, Blender's
    strength 1 gives radiance equal to the colour), on the front face only unless `two_sided`
    (a Mix Shader driven by Geometry > Backfacing; Cycles emits from both sides otherwise);
  * the camera's world matrix is built from our look-at basis (forward = look_at - eye,
    right = forward x up, up' = right x forward; Blender cameras look down local -Z with +Y up),
    with sensor_fit VERTICAL and a lens that gives fov_y;
  * the background is the world's colour at strength 1; the film size is the resolution.

Anything else (spheres, point lights, phong, mirror, dielectric, a thin lens) is rejected with an
error: a tessellated sphere or Blender's light units would not be the same scene.

`--approximate` is for benchmarks that measure each renderer against its own reference
(bench/efficiency.sh), never for references: spheres become smooth-shaded UV spheres (enough
segments that the silhouette is within 0.05 pixel), `mirror` a sharp Glossy BSDF of the
reflectance, `dielectric` a sharp Glass BSDF of the ior (and the tint as its colour, which Cycles
applies to the reflection too). `--res WxH` renders at another film size.

With `--no-light-sampling` emitters are found by BSDF sampling alone (each material's
`sample_as_light` off). The committed references use it: Blender 3.4.1's mesh-light sampling
underestimates direct light at points near the light's plane (by 6% on the Cornell box's upper back
wall; measured against the exact irradiance of the quad light, see
tests/data/references/README.md), while BSDF sampling alone agrees with the exact value.

Cycles is set for an unbiased render comparable to ours: CPU, `--spp` samples in total, a box
pixel filter of width 1 (our camera jitters uniformly inside the pixel), no adaptive sampling, no
denoising, no clamping, no glossy blur, no light threshold, no path guiding, max_bounces =
max_depth - 1 (our max_depth counts scattering vertices; Cycles' bounces count the vertices after
the first), Standard view transform, opaque film, EXR float32 RGB.

With `--seeds K` (K >= 2) the samples are split into K renders of spp/K samples with seeds
S, S+1, ..., S+K-1; OUT.exr is their mean, and OUT-variance.exr holds, per pixel and channel, the
variance of that mean estimated from the spread of the K renders (sum (x_k - mean)^2 / (K (K-1))),
so that a test can account for the reference's own noise. OUT.json records every setting, the
Blender version, the scene's SHA-256, per-channel image means and the render times; the same
settings (JSON) are in both EXR headers as the string attribute `rayfarmReference`. Its
`render_seconds` time each whole render operator (the EXR write included);
`render_only_seconds` and `render_cpu_seconds` run from Blender's render_pre to its render_post
(Cycles' scene sync, BVH and sampling: neither Blender's start, nor the scene build, nor the file).

With `--ladder 1,4,16` the scene is rendered once per sample count with seed S, each image written
by Blender as OUT-<spp>spp.exr (float32 RGB), and the times of each render (as above) go to
OUT.json and OUT.csv: benchmarks of time against error, with one Blender start for the ladder.
"""

import argparse
import hashlib
import json
import math
import os
import struct
import sys
import tempfile
import time

import bpy
from mathutils import Matrix


class SceneFormatError(Exception):
    pass


def strip_json_comments(text):
    """Removes // and /* */ comments outside strings (our scene format allows them)."""
    out, i, n, in_string = [], 0, len(text), False
    while i < n:
        c = text[i]
        if in_string:
            out.append(c)
            if c == "\\" and i + 1 < n:
                out.append(text[i + 1])
                i += 1
            elif c == '"':
                in_string = False
        elif c == '"':
            in_string = True
            out.append(c)
        elif text.startswith("//", i):
            while i < n and text[i] != "\n":
                i += 1
            continue
        elif text.startswith("/*", i):
            end = text.find("*/", i + 2)
            i = n if end < 0 else end + 2
            continue
        else:
            out.append(c)
        i += 1
    return "".join(out)


def sub(a, b):
    return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]


def add(a, b):
    return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def normalize(a):
    length = math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    return [a[0] / length, a[1] / length, a[2] / length]


def read_obj(path, override):
    """Vertices and triangles (with MTL material names, or `override`) of a simple OBJ file."""
    positions, triangles = [], []
    current = None
    with open(path, encoding="utf-8") as f:
        for line_no, line in enumerate(f, 1):
            words = line.split()
            if not words or words[0].startswith("#"):
                continue
            if words[0] == "v":
                positions.append([float(x) for x in words[1:4]])
            elif words[0] == "usemtl":
                current = words[1]
            elif words[0] == "f":
                idx = []
                for w in words[1:]:
                    k = int(w.split("/")[0])
                    idx.append(k - 1 if k > 0 else len(positions) + k)
                for j in range(1, len(idx) - 1):
                    triangles.append(([idx[0], idx[j], idx[j + 1]], override or current))
            elif words[0] not in ("vt", "vn", "o", "g", "s", "mtllib"):
                print(f"{path}:{line_no}: statement {words[0]!r} ignored", file=sys.stderr)
    if override is None:
        raise SceneFormatError(f"{path}: OBJ meshes need a `material` override in this script "
                               "(MTL materials are not translated)")
    return positions, triangles


def load_our_scene(path, approximate=False):
    """Our scene as plain data: camera, film, materials, triangles (vertex triples + material) and,
    with `approximate`, spheres (centre, radius, material)."""
    with open(path, encoding="utf-8") as f:
        doc = json.loads(strip_json_comments(f.read()))
    cam = doc["camera"]
    if cam.get("type", "perspective") != "perspective" or cam.get("aperture_radius", 0) != 0:
        raise SceneFormatError(f"{path}: /camera: only a pinhole perspective camera is supported")
    materials = {}
    approximated = ("mirror", "dielectric") if approximate else ()
    for name, m in doc.get("materials", {}).items():
        if m["type"] != "diffuse" and m["type"] not in approximated:
            supported = "diffuse, mirror, dielectric" if approximate else "diffuse only"
            raise SceneFormatError(f"{path}: /materials/{name}: type {m['type']!r} not supported "
                                   f"({supported})")
        if m["type"] == "mirror":
            materials[name] = {"type": "mirror", "reflectance": m.get("reflectance", [1.0, 1.0, 1.0])}
            continue
        if m["type"] == "dielectric":
            materials[name] = {"type": "dielectric", "ior": float(m.get("ior", 1.5)),
                               "tint": m.get("tint", [1.0, 1.0, 1.0])}
            continue
        materials[name] = {
            "type": "diffuse",
            "albedo": m.get("albedo", [0.8, 0.8, 0.8]),
            "emission": m.get("emission", [0.0, 0.0, 0.0]),
            "two_sided": bool(m.get("two_sided", False)),
        }
    triangles = []  # (v0, v1, v2, material)
    spheres = []  # (centre, radius, material), approximate only
    for i, s in enumerate(doc.get("shapes", [])):
        t = s["type"]
        if t == "quad":
            c, e1, e2 = s["corner"], s["edge1"], s["edge2"]
            p1, p2, p3 = add(c, e1), add(add(c, e1), e2), add(c, e2)
            triangles.append((c, p1, p2, s["material"]))
            triangles.append((c, p2, p3, s["material"]))
        elif t == "triangle":
            v = s["vertices"]
            triangles.append((v[0], v[1], v[2], s["material"]))
        elif t == "mesh":
            obj = os.path.join(os.path.dirname(path), s["file"])
            positions, tris = read_obj(obj, s.get("material"))
            for idx, mat in tris:
                triangles.append((positions[idx[0]], positions[idx[1]], positions[idx[2]], mat))
        elif t == "sphere" and approximate:
            spheres.append((s["center"], float(s["radius"]), s["material"]))
        else:
            raise SceneFormatError(f"{path}: /shapes/{i}: shape type {t!r} not supported")
    if doc.get("lights"):
        raise SceneFormatError(f"{path}: /lights: point lights are not supported")
    for *_, mat in triangles + spheres:
        if mat not in materials:
            raise SceneFormatError(f"{path}: unknown material {mat!r}")
    render = doc.get("render", {})
    return {
        "camera": {
            "eye": cam["eye"], "look_at": cam["look_at"], "up": cam.get("up", [0, 1, 0]),
            "fov_y": cam["fov_y"],
        },
        "film": doc["film"],
        "materials": materials,
        "triangles": triangles,
        "spheres": spheres,
        "background": doc.get("background", [0.0, 0.0, 0.0]),
        # rayfarm's default is no cap; Cycles' largest bounce count (1024) stands in for it.
        "max_depth": 1025 if render.get("max_depth", "unlimited") == "unlimited" else render["max_depth"],
    }


def make_specular(mat, m, nodes, links, out):
    """`--approximate`: a mirror as a sharp Glossy BSDF of its reflectance, a dielectric as a sharp
    Glass BSDF of its ior. Cycles' Glass colour scales reflection too where our tint scales only
    transmission, and Cycles does not scale radiance by the squared ior ratio on crossing: close,
    not the same scene (fine for a benchmark that compares each renderer with itself)."""
    if m["type"] == "mirror":
        bsdf = nodes.new("ShaderNodeBsdfGlossy")
        bsdf.inputs["Color"].default_value = (*m["reflectance"], 1.0)
    else:
        bsdf = nodes.new("ShaderNodeBsdfGlass")
        bsdf.inputs["Color"].default_value = (*m["tint"], 1.0)
        bsdf.inputs["IOR"].default_value = m["ior"]
    bsdf.distribution = "SHARP"
    bsdf.inputs["Roughness"].default_value = 0.0
    links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def make_material(name, m):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    out.target = "CYCLES"
    if m["type"] != "diffuse":
        return make_specular(mat, m, nodes, links, out)
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (*m["albedo"], 1.0)
    diffuse.inputs["Roughness"].default_value = 0.0  # Lambert, not Oren-Nayar
    if not any(e > 0 for e in m["emission"]):
        links.new(diffuse.outputs["BSDF"], out.inputs["Surface"])
        return mat
    emission = nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (*m["emission"], 1.0)
    emission.inputs["Strength"].default_value = 1.0
    stored = list(emission.inputs["Color"].default_value)[:3]
    if any(abs(a - b) > 1e-6 * max(1.0, abs(b)) for a, b in zip(stored, m["emission"])):
        raise SceneFormatError(f"material {name}: Blender stored emission {stored}, not {m['emission']}")
    both = nodes.new("ShaderNodeAddShader")
    links.new(diffuse.outputs["BSDF"], both.inputs[0])
    links.new(emission.outputs["Emission"], both.inputs[1])
    if m["two_sided"]:
        links.new(both.outputs["Shader"], out.inputs["Surface"])
        return mat
    # Our emitters emit from the front face only: the back face gets the diffuse BSDF alone.
    geometry = nodes.new("ShaderNodeNewGeometry")
    diffuse_back = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse_back.inputs["Color"].default_value = (*m["albedo"], 1.0)
    diffuse_back.inputs["Roughness"].default_value = 0.0
    mix = nodes.new("ShaderNodeMixShader")
    links.new(geometry.outputs["Backfacing"], mix.inputs["Fac"])
    links.new(both.outputs["Shader"], mix.inputs[1])          # Fac 0: front face
    links.new(diffuse_back.outputs["BSDF"], mix.inputs[2])    # Fac 1: back face
    links.new(mix.outputs["Shader"], out.inputs["Surface"])
    return mat


def sphere_segments(radius, centre, ours, max_error_px=0.05):
    """Segments around a UV sphere whose silhouette (a polygon inscribed in the circle, off by
    r (1 - cos(pi / n))) stays within `max_error_px` pixels of the true one, seen from the camera."""
    c = ours["camera"]
    distance = max(math.dist(centre, c["eye"]) - radius, 1e-6 * radius)
    pixel = 2.0 * distance * math.tan(math.radians(c["fov_y"]) / 2.0) / ours["film"]["height"]
    cos_half = 1.0 - min(1.0, max_error_px * pixel / radius)
    return max(64, min(1024, math.ceil(math.pi / math.acos(cos_half))))


def add_uv_sphere(scene, name, sphere, material, ours):
    """`--approximate`: our sphere as a smooth-shaded UV sphere with outward faces."""
    import bmesh
    centre, radius, _ = sphere
    segments = sphere_segments(radius, centre, ours)
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=segments // 2, radius=radius)
    bm.to_mesh(mesh)
    bm.free()
    for poly in mesh.polygons:
        poly.use_smooth = True
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = tuple(centre)
    scene.collection.objects.link(obj)
    print(f"{name}: UV sphere of radius {radius} at {centre}, {segments} segments", flush=True)
    return segments


def build_blender_scene(ours):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    # Geometry: one mesh, flat faces with our winding, one material slot per material used.
    names = sorted({t[3] for t in ours["triangles"]})
    slot = {n: i for i, n in enumerate(names)}
    verts, faces = [], []
    for v0, v1, v2, _ in ours["triangles"]:
        base = len(verts)
        verts += [tuple(v0), tuple(v1), tuple(v2)]
        faces.append((base, base + 1, base + 2))
    mesh = bpy.data.meshes.new("scene")
    mesh.from_pydata(verts, [], faces)
    mesh.validate()
    for n in names:
        mesh.materials.append(make_material(n, ours["materials"][n]))
    for poly, tri in zip(mesh.polygons, ours["triangles"]):
        poly.material_index = slot[tri[3]]
        poly.use_smooth = False
    if len(mesh.polygons) != len(ours["triangles"]):
        raise SceneFormatError(f"Blender kept {len(mesh.polygons)} of {len(ours['triangles'])} triangles")
    obj = bpy.data.objects.new("scene", mesh)
    scene.collection.objects.link(obj)
    made = {n: mesh.materials[i] for i, n in enumerate(names)}
    for k, sphere in enumerate(ours["spheres"]):
        name = sphere[2]
        if name not in made:
            made[name] = make_material(name, ours["materials"][name])
        add_uv_sphere(scene, f"sphere-{k}", sphere, made[name], ours)

    # Camera: world matrix from our look-at basis; vertical field of view.
    c = ours["camera"]
    forward = normalize(sub(c["look_at"], c["eye"]))
    right = normalize(cross(forward, c["up"]))
    up = cross(right, forward)
    cam_data = bpy.data.cameras.new("camera")
    cam_data.type = "PERSP"
    cam_data.sensor_fit = "VERTICAL"
    cam_data.sensor_height = 24.0
    cam_data.lens = cam_data.sensor_height / (2.0 * math.tan(math.radians(c["fov_y"]) / 2.0))
    cam_data.shift_x = cam_data.shift_y = 0.0
    cam_data.clip_start = 1e-3
    cam_data.clip_end = 1e7
    cam_obj = bpy.data.objects.new("camera", cam_data)
    cam_obj.matrix_world = Matrix((
        (right[0], up[0], -forward[0], c["eye"][0]),
        (right[1], up[1], -forward[1], c["eye"][1]),
        (right[2], up[2], -forward[2], c["eye"][2]),
        (0.0, 0.0, 0.0, 1.0),
    ))
    scene.collection.objects.link(cam_obj)
    scene.camera = cam_obj

    # World: our background radiance (black for the Cornell box).
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*ours["background"], 1.0)
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world
    return scene


def configure_cycles(scene, ours, spp, threads):
    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x = ours["film"]["width"]
    r.resolution_y = ours["film"]["height"]
    r.resolution_percentage = 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.use_border = False
    r.use_motion_blur = False
    r.film_transparent = False
    r.use_compositing = False
    r.use_sequencer = False
    r.use_persistent_data = False
    r.threads_mode = "FIXED" if threads > 0 else "AUTO"
    if threads > 0:
        r.threads = threads
    r.use_stamp = False  # never burn text into the image; metadata only
    s = r.image_settings
    s.file_format = "OPEN_EXR"
    s.color_depth = "32"
    s.color_mode = "RGB"
    s.exr_codec = "ZIP"
    s.use_preview = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.sequencer_colorspace_settings.name = "Linear"

    cy = scene.cycles
    cy.device = "CPU"
    cy.feature_set = "SUPPORTED"
    cy.shading_system = False  # SVM, not OSL
    cy.samples = spp
    cy.sample_offset = 0
    cy.time_limit = 0.0
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.use_preview_denoising = False
    cy.use_animated_seed = False
    cy.sampling_pattern = "PROGRESSIVE_MULTI_JITTER"
    cy.auto_scrambling_distance = False
    cy.scrambling_distance = 1.0
    cy.pixel_filter_type = "BOX"
    cy.filter_width = 1.0
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.blur_glossy = 0.0
    cy.caustics_reflective = True
    cy.caustics_refractive = True
    cy.light_sampling_threshold = 0.0
    # Has no effect in Blender 3.4 release builds (a debug setting); recorded for completeness.
    cy.direct_light_sampling_type = "MULTIPLE_IMPORTANCE_SAMPLING"
    cy.min_light_bounces = 0
    cy.min_transparent_bounces = 0
    cy.use_guiding = False
    cy.use_fast_gi = False
    cy.film_exposure = 1.0
    # Our max_depth counts scattering vertices including the camera ray's hit; Cycles counts
    # bounces after it (0 bounces = direct lighting = our max_depth 1).
    bounces = max(0, ours["max_depth"] - 1)
    cy.max_bounces = bounces
    cy.diffuse_bounces = bounces
    cy.glossy_bounces = bounces
    cy.transmission_bounces = bounces
    cy.volume_bounces = bounces
    cy.transparent_max_bounces = bounces
    cy.use_layer_samples = "IGNORE"
    vl = scene.view_layers[0]
    vl.use_pass_combined = True
    vl.samples = 0
    return bounces


SETTINGS_RECORDED = [
    "device", "feature_set", "samples", "sample_offset", "use_adaptive_sampling", "use_denoising",
    "use_animated_seed", "sampling_pattern", "auto_scrambling_distance", "scrambling_distance",
    "pixel_filter_type", "filter_width", "sample_clamp_direct", "sample_clamp_indirect",
    "blur_glossy", "caustics_reflective", "caustics_refractive", "light_sampling_threshold",
    "direct_light_sampling_type", "min_light_bounces", "min_transparent_bounces", "use_guiding",
    "use_fast_gi", "film_exposure", "max_bounces", "diffuse_bounces", "glossy_bounces",
    "transmission_bounces", "volume_bounces", "transparent_max_bounces",
]


def recorded_settings(scene):
    cy, r = scene.cycles, scene.render
    out = {k: getattr(cy, k) for k in SETTINGS_RECORDED}
    cam = scene.camera.data
    out.update({
        "resolution": [r.resolution_x, r.resolution_y],
        "film_transparent": r.film_transparent,
        "view_transform": scene.view_settings.view_transform,
        "look": scene.view_settings.look,
        "exposure": scene.view_settings.exposure,
        "gamma": scene.view_settings.gamma,
        "scene_linear_space": scene.display_settings.display_device + " display, linear Rec.709 scene",
        "output": f"{r.image_settings.file_format} {r.image_settings.color_depth}-bit float "
                  f"{r.image_settings.color_mode} {r.image_settings.exr_codec}",
        "camera_sensor_fit": cam.sensor_fit,
        "camera_sensor_height_mm": cam.sensor_height,
        "camera_lens_mm": cam.lens,
        "camera_angle_y_deg": math.degrees(cam.angle_y),
        "camera_matrix_world": [list(row) for row in scene.camera.matrix_world],
        "world": "Background colour = scene background, strength 1",
        "threads": r.threads if r.threads_mode == "FIXED" else "auto",
    })
    return out


def load_pixels(path, width, height):
    """RGB float pixels of an EXR, top row first (Blender's buffers start at the bottom row)."""
    img = bpy.data.images.load(path, check_existing=False)
    img.colorspace_settings.name = "Linear"  # no conversion: the file holds scene-linear values
    flat = list(img.pixels)
    ch = img.channels
    if (img.size[0], img.size[1]) != (width, height):
        raise RuntimeError(f"{path}: size {tuple(img.size)}, expected {(width, height)}")
    rows = []
    for y in range(height - 1, -1, -1):
        row = []
        for x in range(width):
            i = (y * width + x) * ch
            row += flat[i:i + 3]
        rows.append(row)
    bpy.data.images.remove(img)
    return [v for row in rows for v in row]


def to_float32(x):
    return struct.unpack("f", struct.pack("f", x))[0]


def write_exr_rgb(path, rgb, width, height, attributes):
    """Writes top-row-first RGB floats as an uncompressed float32 scanline EXR, with string
    header attributes (our own writer: Blender cannot put metadata on an image it did not render)."""
    def attr(name, type_name, payload):
        return name.encode() + b"\0" + type_name.encode() + b"\0" + struct.pack("<i", len(payload)) + payload

    chlist = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for c in "BGR") + b"\0"
    box = struct.pack("<4i", 0, 0, width - 1, height - 1)
    header = b"".join([
        attr("channels", "chlist", chlist),
        attr("compression", "compression", b"\0"),  # NO_COMPRESSION
        attr("dataWindow", "box2i", box),
        attr("displayWindow", "box2i", box),
        attr("lineOrder", "lineOrder", b"\0"),  # INCREASING_Y
        attr("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        attr("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0)),
        attr("screenWindowWidth", "float", struct.pack("<f", 1.0)),
    ] + [attr(k, "string", v.encode()) for k, v in sorted(attributes.items())]) + b"\0"
    prefix = struct.pack("<ii", 20000630, 2) + header
    line_bytes = 8 + 3 * 4 * width
    table_end = len(prefix) + 8 * height
    offsets = struct.pack(f"<{height}Q", *(table_end + y * line_bytes for y in range(height)))
    lines = []
    for y in range(height):
        row = rgb[y * width * 3:(y + 1) * width * 3]
        data = b"".join(struct.pack(f"<{width}f", *row[c::3]) for c in (2, 1, 0))  # B, G, R
        lines.append(struct.pack("<ii", y, len(data)) + data)
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(prefix + offsets + b"".join(lines))
    os.replace(tmp, path)


def save_pixels(rgb, width, height, path, attributes):
    """Writes an EXR (float32 RGB, with `attributes`) and checks that Blender reads back every value."""
    rgb = [to_float32(v) for v in rgb]
    write_exr_rgb(path, rgb, width, height, attributes)
    back = load_pixels(path, width, height)
    worst = max(abs(a - b) for a, b in zip(back, rgb))
    if worst != 0.0:
        raise RuntimeError(f"{path}: read back with a difference of {worst}")


def timed_render(scene):
    """Renders the scene's still to its filepath. Returns the seconds of the whole render operator
    and, from Blender's render_pre to its render_post, the wall and process CPU seconds of the
    render itself: Cycles' scene sync, BVH and sampling, without Blender's start, the scene build
    above or the file written after."""
    marks = {}

    def pre(*_):
        marks["pre"] = (time.monotonic(), time.process_time())

    def post(*_):
        marks["post"] = (time.monotonic(), time.process_time())

    bpy.app.handlers.render_pre.append(pre)
    bpy.app.handlers.render_post.append(post)
    try:
        t0 = time.monotonic()
        bpy.ops.render.render(write_still=True)
        total = time.monotonic() - t0
    finally:
        bpy.app.handlers.render_pre.remove(pre)
        bpy.app.handlers.render_post.remove(post)
    if "pre" not in marks or "post" not in marks:
        raise RuntimeError("Blender did not report the start and end of the render")
    return {"seconds": total, "render_seconds": marks["post"][0] - marks["pre"][0],
            "render_cpu_seconds": marks["post"][1] - marks["pre"][1]}


def render_seeds(scene, seeds, per_render, width, height, timings=None):
    """Renders `scene` once per seed; (renders, seconds each, per-pixel mean, variance of that
    mean from the spread of the renders: sum (x_k - mean)^2 / (K (K - 1)), None for one render).
    Each render's timed_render figures are appended to `timings` when given."""
    renders, times = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k, seed in enumerate(seeds):
            scene.cycles.seed = seed
            scene.render.filepath = os.path.join(tmp, f"render-{k}.exr")
            timing = timed_render(scene)
            times.append(timing["seconds"])
            if timings is not None:
                timings.append(timing)
            print(f"render {k + 1}/{len(seeds)}: seed {seed}, {per_render} spp, {times[-1]:.1f} s",
                  flush=True)
            renders.append(load_pixels(scene.render.filepath, width, height))
    n = len(renders)
    mean = [sum(r[i] for r in renders) / n for i in range(len(renders[0]))]
    var = None
    if n >= 2:
        var = [sum((r[i] - mean[i]) ** 2 for r in renders) / (n * (n - 1)) for i in range(len(mean))]
    return renders, times, mean, var


def render_ladder(scene, args, argv, ladder, stem):
    """`--ladder`: one render per sample count, written by Blender as STEM-<spp>spp.exr (scene-linear
    float32 RGB), and STEM.json with each render's times (timed_render)."""
    os.makedirs(os.path.dirname(os.path.abspath(stem)) or ".", exist_ok=True)
    renders = []
    scene.cycles.seed = args.seed
    for spp in ladder:
        scene.cycles.samples = spp
        path = f"{stem}-{spp}spp.exr"
        scene.render.filepath = os.path.abspath(path)
        timing = timed_render(scene)
        if not os.path.exists(scene.render.filepath):
            raise RuntimeError(f"Blender did not write {path}")
        renders.append({"spp": spp, "seed": args.seed, "file": os.path.basename(path),
                        **{k: round(v, 4) for k, v in timing.items()}})
        print(f"ladder: {spp} spp, seed {args.seed}: {timing['render_seconds']:.3f} s "
              f"(render_pre to render_post)", flush=True)
    meta = {
        "what": "Blender Cycles renders of a rayfarm scene at several sample counts "
                "(scripts/blender_reference.py --ladder)",
        "blender_version": bpy.app.version_string,
        "scene": args.source_name or args.scene,
        "scene_sha256": hashlib.sha256(open(args.scene, "rb").read()).hexdigest(),
        "approximate": args.approximate,
        "material_sample_as_light": not args.no_light_sampling,
        "cycles": recorded_settings(scene),
        "timing": "seconds: the whole render operator, file write included; render_seconds and "
                  "render_cpu_seconds: Blender's render_pre to render_post (wall, and CPU of the "
                  "process)",
        "renders": renders,
        "command": "blender -b --factory-startup --python scripts/blender_reference.py -- "
                   + " ".join(argv),
    }
    with open(stem + ".json", "w", encoding="utf-8") as f:
        json.dump(meta, f, indent=2)
        f.write("\n")
    with open(stem + ".csv", "w", encoding="utf-8") as f:  # the same times, for shell scripts
        f.write("spp,seed,seconds,render_seconds,render_cpu_seconds,file\n")
        for r in renders:
            f.write(f"{r['spp']},{r['seed']},{r['seconds']},{r['render_seconds']},"
                    f"{r['render_cpu_seconds']},{r['file']}\n")


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="blender -b --python scripts/blender_reference.py --")
    ap.add_argument("scene")
    ap.add_argument("out")
    ap.add_argument("--spp", type=int, help="samples per pixel in total")
    ap.add_argument("--seeds", type=int, default=1, help="independent renders (spp split evenly)")
    ap.add_argument("--seed", type=int, default=1, help="first Cycles seed")
    ap.add_argument("--threads", type=int, default=0, help="render threads (0 = all)")
    ap.add_argument("--source-name", default=None, help="scene path to record (default: as given)")
    ap.add_argument("--no-light-sampling", action="store_true",
                    help="emitters are found by BSDF sampling alone (the materials' "
                         "sample_as_light off): Cycles 3.4's mesh-light sampling is biased low "
                         "near the light's plane (tests/data/references/README.md)")
    ap.add_argument("--approximate", action="store_true",
                    help="for benchmarks only: spheres become smooth UV spheres, mirror a sharp "
                         "Glossy BSDF, dielectric a sharp Glass BSDF (not the same scene)")
    ap.add_argument("--res", default=None, metavar="WxH", help="film size instead of the scene's")
    ap.add_argument("--ladder", default=None, metavar="SPP,SPP,...",
                    help="one render per sample count (seed --seed), each written by Blender as "
                         "OUT-<spp>spp.exr, their times in OUT.json and OUT.csv; no mean, no "
                         "variance")
    args = ap.parse_args(argv)
    ladder = None
    if args.ladder is not None:
        try:
            ladder = [int(x) for x in args.ladder.split(",")]
        except ValueError:
            ap.error(f"--ladder {args.ladder}: expected sample counts separated by commas")
        if not ladder or min(ladder) < 1 or args.spp is not None or args.seeds != 1:
            ap.error("--ladder takes counts >= 1, and neither --spp nor --seeds")
    elif args.spp is None:
        ap.error("--spp (or --ladder) is required")
    elif args.seeds < 1 or args.spp % args.seeds != 0:
        ap.error("--spp must be a multiple of --seeds")

    stem = os.path.splitext(args.out)[0]
    if os.path.abspath(stem + ".json") == os.path.abspath(args.scene):
        ap.error(f"the settings file {stem}.json would overwrite the scene: choose another OUT name")
    ours = load_our_scene(args.scene, approximate=args.approximate)
    if args.res is not None:
        w, _, h = args.res.lower().partition("x")
        if not (w.isdigit() and h.isdigit() and int(w) > 0 and int(h) > 0):
            ap.error(f"--res {args.res}: expected WIDTHxHEIGHT, e.g. 128x128")
        ours["film"] = {"width": int(w), "height": int(h)}
    scene = build_blender_scene(ours)
    if ladder is not None:
        configure_cycles(scene, ours, ladder[0], args.threads)
        for mat in bpy.data.materials:
            mat.cycles.sample_as_light = not args.no_light_sampling
        render_ladder(scene, args, argv, ladder, stem)
        return
    per_render = args.spp // args.seeds
    bounces = configure_cycles(scene, ours, per_render, args.threads)
    for mat in bpy.data.materials:
        mat.cycles.sample_as_light = not args.no_light_sampling
    w, h = ours["film"]["width"], ours["film"]["height"]

    settings = recorded_settings(scene)
    meta = {
        "what": "Blender Cycles reference of a rayfarm scene (scripts/blender_reference.py)",
        "blender_version": bpy.app.version_string,
        "scene": args.source_name or args.scene,
        "scene_sha256": hashlib.sha256(open(args.scene, "rb").read()).hexdigest(),
        "spp_total": args.spp,
        "renders": args.seeds,
        "spp_per_render": per_render,
        "seeds": list(range(args.seed, args.seed + args.seeds)),
        "our_max_depth": ours["max_depth"],
        "cycles_max_bounces": bounces,
        "max_bounces_rule": "Cycles bounces = our max_depth - 1 (ours counts the camera ray's hit "
                            "as the first scattering vertex; Cycles' 0 bounces is direct light)",
        "pixel_filter": "box of width 1 pixel (ours: uniform jitter in the pixel, renderer/camera.h)",
        "emission": "Emission shader strength 1, colour = our emission radiance; front face only "
                    "(Mix Shader on Geometry.Backfacing) unless two_sided",
        "diffuse": "Diffuse BSDF roughness 0 (Lambert), colour = our albedo",
        "cycles": settings,
        "material_sample_as_light": not args.no_light_sampling,
        "command": "blender -b --factory-startup --python scripts/blender_reference.py -- "
                   + " ".join(argv),
    }
    scene.render.use_stamp_note = True
    scene.render.stamp_note_text = json.dumps({k: meta[k] for k in ("blender_version", "scene",
                                               "spp_per_render", "cycles_max_bounces")})

    timings = []
    renders, times, mean, var = render_seeds(scene, meta["seeds"], per_render, w, h, timings)
    n = len(renders)
    out_dir = os.path.dirname(os.path.abspath(args.out))
    os.makedirs(out_dir, exist_ok=True)
    files = {"mean": os.path.basename(args.out)}
    if n >= 2:
        files["variance_of_mean"] = os.path.basename(stem + "-variance.exr")
    meta["files"] = files
    settings_text = json.dumps({k: v for k, v in meta.items() if k != "files"}, sort_keys=True)
    save_pixels(mean, w, h, args.out, {
        "comments": f"Blender Cycles reference of {meta['scene']}: mean of {n} renders, "
                    f"{args.spp} spp in all (scripts/blender_reference.py)",
        "rayfarmReference": settings_text})
    if n >= 2:
        save_pixels(var, w, h, stem + "-variance.exr", {
            "comments": f"per-pixel variance of the mean of {os.path.basename(args.out)}, from the "
                        f"spread of its {n} independent renders",
            "rayfarmReference": settings_text})
    meta["image_mean_rgb"] = [sum(mean[c::3]) / (w * h) for c in range(3)]
    meta["render_seconds"] = [round(t, 2) for t in times]
    meta["render_only_seconds"] = [round(t["render_seconds"], 3) for t in timings]
    meta["render_cpu_seconds"] = [round(t["render_cpu_seconds"], 3) for t in timings]
    meta["timing"] = ("render_seconds: the whole render operator, file write included; "
                      "render_only_seconds and render_cpu_seconds: Blender's render_pre to "
                      "render_post (wall, and CPU of the process)")
    with open(stem + ".json", "w", encoding="utf-8") as f:
        json.dump(meta, f, indent=2)
        f.write("\n")
    print(f"wrote {args.out} ({', '.join(files.values())}), {stem}.json; "
          f"{sum(times):.1f} s of rendering", flush=True)


if __name__ == "__main__":  # scripts/blender_gltf_reference.py imports the pieces above
    try:
        main()
    except Exception as e:  # Blender keeps running after a script error; fail the process instead
        import traceback
        traceback.print_exc()
        sys.exit(1)
