"""Builds a small glTF test scene in Blender, exports it, and renders it with Cycles.

    blender -b --factory-startup --python scripts/blender_gltf_reference.py -- \
        OUT_DIR [--scene showcase|lights] --spp N [--seeds K] [--seed S] [--threads T]

Two scenes: `showcase` (this file, described below) and `lights` (Blender's punctual lamps and a
normal map: scripts/blender_gltf_lights.py, which lists its files). For showcase, writes into
OUT_DIR (tests/data/gltf-references/):

  showcase.gltf, showcase.bin, floor-texture.png   Blender's glTF exporter ("glTF Separate")
  showcase-scene.json    our JSON scene naming showcase.gltf, replacing the materials whose glTF
                         meaning differs from what Cycles renders (see below)
  showcase-cycles.exr    Cycles' render of the same Blender scene: the mean of K renders
  showcase-cycles-variance.exr, showcase-cycles.json   as scripts/blender_reference.py writes them

The scene: a textured floor and a grey back wall, an emissive quad light, a glass cube, and one
smooth-shaded mirror ellipsoid mesh placed twice (two objects sharing the mesh data, rotated and
scaled differently), seen by a Blender camera. Every material is a Principled BSDF when exported;
for the render, the materials whose glTF reading is not what Cycles' Principled BSDF computes are
given node trees that our JSON scene can state exactly:

  * mirror: Principled metallic 1, roughness 0, base colour white, rendered as is. Both Schlick's
    Fresnel (glTF) and Cycles' metallic Fresnel are 1 for a white base: a perfect mirror.
  * glass: Principled transmission 1, roughness 0, ior 1.5, white, rendered as is: Cycles refracts
    (a solid glass cube). glTF's KHR_materials_transmission without KHR_materials_volume is
    thin-walled (no refraction), so our scene replaces it with a `dielectric` of ior 1.5.
  * floor: exported as Principled with the image as base colour; rendered as a Diffuse BSDF of
    roughness 0 (Lambert) reading the same image (Closest interpolation). Our scene replaces it with
    a `diffuse` material reading the image through a `textures` entry with uv_origin top_left.
  * wall: Principled grey when exported, a Diffuse BSDF (Lambert) of that grey when rendered; ours
    `diffuse`.
  * light: exported as Principled black with an emission; rendered as an Emission shader alone
    (both faces emit); ours `diffuse` of albedo 0 with that emission, two_sided. Found by BSDF
    sampling only in Cycles (sample_as_light off): Blender 3.4.1's mesh-light sampling is biased
    near the light's plane (tests/data/references/README.md).

Cycles is configured by scripts/blender_reference.py's configure_cycles (CPU, box filter width 1,
no adaptive sampling, denoising or clamping, Standard view, ...), with max_bounces = MAX_DEPTH - 1.
"""

import argparse
import hashlib
import json
import math
import os
import sys

import bpy
from mathutils import Euler, Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_reference import (configure_cycles, recorded_settings, render_seeds,  # noqa: E402
                               save_pixels)

NAME = "showcase"
WIDTH, HEIGHT = 64, 48
MAX_DEPTH = 8
LIGHT_RADIANCE = 6.0
WALL_GREY = 0.6
TEXTURE = "floor-texture"
# 4x4 texels, top row first, every texel distinct: a flip or mirror of u or v moves colours.
TEXELS = [
    [(0.9, 0.1, 0.1), (0.9, 0.9, 0.1), (0.1, 0.9, 0.1), (0.1, 0.9, 0.9)],
    [(0.8, 0.8, 0.8), (0.1, 0.1, 0.9), (0.9, 0.1, 0.9), (0.5, 0.3, 0.1)],
    [(0.2, 0.2, 0.2), (0.6, 0.9, 0.3), (0.3, 0.5, 0.9), (0.9, 0.6, 0.2)],
    [(0.1, 0.5, 0.3), (0.7, 0.2, 0.4), (0.4, 0.4, 0.7), (0.05, 0.05, 0.05)],
]


def principled(name, **inputs):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    node = mat.node_tree.nodes["Principled BSDF"]
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    return mat, node


def mesh_object(name, verts, faces, uvs=None, material=None):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    if uvs is not None:
        layer = mesh.uv_layers.new(name="UVMap")
        for loop in mesh.loops:
            layer.data[loop.index].uv = uvs[loop.vertex_index]
    mesh.validate()
    for p in mesh.polygons:
        p.use_smooth = False
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def make_texture(out_dir):
    img = bpy.data.images.new(TEXTURE, 4, 4, alpha=False, float_buffer=False)
    flat = []
    for row in reversed(TEXELS):  # Blender's pixels start at the bottom row
        for rgb in row:
            flat += [*rgb, 1.0]
    img.pixels = flat
    img.filepath_raw = os.path.join(out_dir, TEXTURE + ".png")
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)
    # Read back from the file, so that Cycles and the exporter see its 8-bit values.
    img = bpy.data.images.load(os.path.join(out_dir, TEXTURE + ".png"))
    img.name = TEXTURE
    img.colorspace_settings.name = "sRGB"
    return img


def build_scene(out_dir):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    image = make_texture(out_dir)

    floor_mat, floor_node = principled("floor", Roughness=1.0)
    tex = floor_mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = "Closest"
    tex.extension = "REPEAT"
    floor_mat.node_tree.links.new(tex.outputs["Color"], floor_node.inputs["Base Color"])
    wall_mat, _ = principled("wall", **{"Base Color": (WALL_GREY, WALL_GREY, WALL_GREY, 1.0),
                                        "Roughness": 1.0})
    light_mat, _ = principled("light", **{"Base Color": (0.0, 0.0, 0.0, 1.0),
                                          "Emission": (1.0, 1.0, 1.0, 1.0),
                                          "Emission Strength": LIGHT_RADIANCE})
    mirror_mat, _ = principled("mirror", **{"Base Color": (1.0, 1.0, 1.0, 1.0), "Metallic": 1.0,
                                            "Roughness": 0.0})
    glass_mat, _ = principled("glass", **{"Base Color": (1.0, 1.0, 1.0, 1.0), "Transmission": 1.0,
                                          "Roughness": 0.0, "IOR": 1.5})

    # Floor: uv (0, 0) at its (-x, -y) corner, the one nearest the camera's left.
    mesh_object("floor", [(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], [(0, 1, 2, 3)],
                uvs=[(0, 0), (1, 0), (1, 1), (0, 1)], material=floor_mat)
    # The wall stays below the light's plane: points above it would see only the light's back face,
    # edge-on, lit by rare paths whose heavy-tailed estimates make poor z-scores.
    mesh_object("wall", [(-2, 2, 0), (2, 2, 0), (2, 2, 2.2), (-2, 2, 2.2)], [(0, 3, 2, 1)],
                material=wall_mat)
    mesh_object("light", [(-0.6, -0.8, 2.4), (0.6, -0.8, 2.4), (0.6, 0.4, 2.4), (-0.6, 0.4, 2.4)],
                [(0, 3, 2, 1)], material=light_mat)
    h = 0.3
    cube_v = [(x, y, z) for z in (-h, h) for y in (-h, h) for x in (-h, h)]
    cube_f = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    cube = mesh_object("glass", cube_v, cube_f, material=glass_mat)
    cube.location = (0.7, -0.7, 0.35)
    cube.rotation_euler = Euler((0.0, 0.0, 0.6))

    # One smooth-shaded sphere mesh, placed twice (a linked duplicate: one glTF mesh, two nodes).
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=0.5)
    ball = bpy.context.active_object
    ball.name = "ball.A"
    ball.data.name = "ball"
    for p in ball.data.polygons:
        p.use_smooth = True
    ball.data.materials.append(mirror_mat)
    ball.location = (-0.9, 0.3, 0.55)
    ball.rotation_euler = Euler((0.4, 0.3, 0.9))
    ball.scale = (1.2, 0.6, 0.9)
    twin = bpy.data.objects.new("ball.B", ball.data)
    scene.collection.objects.link(twin)
    twin.location = (0.4, 0.8, 0.45)
    twin.rotation_euler = Euler((0.0, -0.5, 2.0))
    twin.scale = (0.7, 0.7, 0.8)

    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens = 32.0
    cam_data.sensor_width = 36.0
    cam_data.sensor_fit = "AUTO"
    cam_data.clip_start = 1e-3
    cam_data.clip_end = 1e4
    cam = bpy.data.objects.new("camera", cam_data)
    cam.location = (0.3, -4.6, 1.8)
    cam.rotation_euler = (Vector((0.0, 0.3, 0.8)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam

    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    return scene, image


def replace_tree(mat, build):
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    out.target = "CYCLES"
    links.new(build(nodes, links), out.inputs["Surface"])


def lambert(nodes, colour):
    d = nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = colour
    d.inputs["Roughness"].default_value = 0.0  # Lambert, not Oren-Nayar
    return d


def set_render_materials(image):
    def floor(nodes, links):
        d = lambert(nodes, (1, 1, 1, 1))
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = image
        tex.interpolation = "Closest"
        tex.extension = "REPEAT"
        links.new(tex.outputs["Color"], d.inputs["Color"])
        return d.outputs["BSDF"]

    def emission(nodes, links):
        e = nodes.new("ShaderNodeEmission")
        e.inputs["Color"].default_value = (1, 1, 1, 1)
        e.inputs["Strength"].default_value = LIGHT_RADIANCE
        return e.outputs["Emission"]

    replace_tree(bpy.data.materials["floor"], floor)
    replace_tree(bpy.data.materials["wall"],
                 lambda nodes, links: lambert(nodes, (WALL_GREY, WALL_GREY, WALL_GREY, 1)).outputs["BSDF"])
    replace_tree(bpy.data.materials["light"], emission)
    for mat in bpy.data.materials:
        mat.cycles.sample_as_light = False


def our_scene():
    """Our JSON scene: the glTF file, the film, and the materials replaced as the docstring says."""
    return {
        "format": 1,
        "gltf": {"file": NAME + ".gltf"},
        "film": {"width": WIDTH, "height": HEIGHT},
        "textures": {"floor": {"type": "image", "file": TEXTURE + ".png", "color_space": "srgb",
                               "filter": "nearest", "wrap": "repeat", "uv_origin": "top_left"}},
        "materials": {
            "floor": {"type": "diffuse", "albedo": {"texture": "floor"}},
            "wall": {"type": "diffuse", "albedo": [WALL_GREY] * 3},
            "light": {"type": "diffuse", "albedo": [0, 0, 0], "emission": [LIGHT_RADIANCE] * 3,
                      "two_sided": True},
            "glass": {"type": "dielectric", "ior": 1.5},
        },
        "render": {"max_depth": MAX_DEPTH},
    }


def export_gltf(path, **options):
    bpy.ops.export_scene.gltf(filepath=path, export_format="GLTF_SEPARATE", export_cameras=True,
                              export_yup=True, export_apply=False, export_texcoords=True,
                              export_normals=True, export_materials="EXPORT",
                              export_image_format="AUTO", export_extras=False,
                              use_selection=False, **options)


def write_json(path, value):
    with open(path, "w", encoding="utf-8") as f:
        json.dump(value, f, indent=2)
        f.write("\n")


def prepare_showcase(out_dir):
    """Builds and exports the showcase scene, then gives it its render materials."""
    scene, image = build_scene(out_dir)
    export_gltf(os.path.join(out_dir, NAME + ".gltf"), export_lights=False)
    write_json(os.path.join(out_dir, NAME + "-scene.json"), our_scene())
    set_render_materials(image)
    materials = {
        "mirror": "Principled BSDF as exported (metallic 1, roughness 0, white)",
        "glass": "Principled BSDF as exported (transmission 1, roughness 0, ior 1.5, white)",
        "floor": "Diffuse BSDF roughness 0 with the image, Closest interpolation",
        "wall": f"Diffuse BSDF roughness 0, colour {WALL_GREY}",
        "light": f"Emission shader, white, strength {LIGHT_RADIANCE}, both faces",
    }
    return scene, NAME, [NAME], WIDTH, HEIGHT, MAX_DEPTH, materials


def prepare_lights(out_dir):
    """Builds the lights scene, exports it with and without tangents (Blender's standard
    photometric lamp units), then gives it its render materials and spot profile."""
    import blender_gltf_lights as lights
    helpers = {"principled": principled, "mesh_object": mesh_object, "replace_tree": replace_tree,
               "lambert": lambert}
    state = lights.build(out_dir, helpers)
    for name, tangents in ((lights.NAME, True), (lights.NAME_NO_TANGENTS, False)):
        export_gltf(os.path.join(out_dir, name + ".gltf"), export_lights=True,
                    export_tangents=tangents, convert_lighting_mode="SPEC")
        write_json(os.path.join(out_dir, name + "-scene.json"), lights.our_scene(name))
    lights.set_render_materials(state, helpers)
    return (state["scene"], lights.NAME, [lights.NAME, lights.NAME_NO_TANGENTS], lights.WIDTH,
            lights.HEIGHT, lights.MAX_DEPTH, lights.materials_rendered())


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="blender -b --python scripts/blender_gltf_reference.py --")
    ap.add_argument("out_dir")
    ap.add_argument("--scene", choices=("showcase", "lights"), default="showcase")
    ap.add_argument("--spp", type=int, required=True, help="samples per pixel in total")
    ap.add_argument("--seeds", type=int, default=8, help="independent renders (spp split evenly)")
    ap.add_argument("--seed", type=int, default=1, help="first Cycles seed")
    ap.add_argument("--threads", type=int, default=0, help="render threads (0 = all)")
    args = ap.parse_args(argv)
    if args.seeds < 2 or args.spp % args.seeds != 0:
        ap.error("--spp must be a multiple of --seeds, and --seeds at least 2")
    out_dir = os.path.abspath(args.out_dir)
    os.makedirs(out_dir, exist_ok=True)

    prepare = prepare_lights if args.scene == "lights" else prepare_showcase
    scene, name, gltf_names, width, height, max_depth, materials = prepare(out_dir)
    per_render = args.spp // args.seeds
    bounces = configure_cycles(scene, {"film": {"width": width, "height": height},
                                       "max_depth": max_depth}, per_render, args.threads)
    settings = recorded_settings(scene)
    settings["world"] = "black, strength 0"
    settings["camera_type"] = scene.camera.data.type
    settings["camera_ortho_scale"] = scene.camera.data.ortho_scale

    def sha256(gltf):
        return hashlib.sha256(open(os.path.join(out_dir, gltf + ".gltf"), "rb").read()).hexdigest()

    meta = {
        "what": "Blender Cycles render of the Blender scene exported as " + name + ".gltf "
                "(scripts/blender_gltf_reference.py)",
        "blender_version": bpy.app.version_string,
        "gltf": name + ".gltf",
        "gltf_sha256": sha256(name),
        "gltf_files_sha256": {g + ".gltf": sha256(g) for g in gltf_names},
        "spp_total": args.spp,
        "renders": args.seeds,
        "spp_per_render": per_render,
        "seeds": list(range(args.seed, args.seed + args.seeds)),
        "our_max_depth": max_depth,
        "cycles_max_bounces": bounces,
        "materials_rendered": materials,
        "material_sample_as_light": False,
        "cycles": settings,
        "command": "blender -b --factory-startup --python scripts/blender_gltf_reference.py -- "
                   + " ".join(argv),
    }
    renders, times, mean, var = render_seeds(scene, meta["seeds"], per_render, width, height)
    n = len(renders)
    stem = os.path.join(out_dir, name + "-cycles")
    settings_text = json.dumps(meta, sort_keys=True)
    save_pixels(mean, width, height, stem + ".exr", {
        "comments": f"Blender Cycles render of {name}.gltf's Blender scene: mean of {n} renders, "
                    f"{args.spp} spp in all (scripts/blender_gltf_reference.py)",
        "rayfarmReference": settings_text})
    save_pixels(var, width, height, stem + "-variance.exr", {
        "comments": f"per-pixel variance of the mean of {name}-cycles.exr, from the spread of its "
                    f"{n} independent renders",
        "rayfarmReference": settings_text})
    meta["files"] = {"mean": name + "-cycles.exr", "variance_of_mean": name + "-cycles-variance.exr"}
    meta["image_mean_rgb"] = [sum(mean[c::3]) / (width * height) for c in range(3)]
    meta["render_seconds"] = [round(t, 2) for t in times]
    write_json(stem + ".json", meta)
    print(f"wrote {out_dir}: {', '.join(g + '.gltf' for g in gltf_names)} and their files, "
          f"{name}-cycles*.exr; {sum(times):.1f} s of rendering", flush=True)


if __name__ == "__main__":
    try:
        main()
    except Exception:  # Blender keeps running after a script error; fail the process instead
        import traceback
        traceback.print_exc()
        sys.exit(1)
