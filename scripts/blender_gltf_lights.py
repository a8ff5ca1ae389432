"""The `lights` scene of scripts/blender_gltf_reference.py: Blender's three punctual lamps and a
tangent-space normal map, exported by Blender's glTF exporter and rendered by Cycles.

Not run on its own: blender_gltf_reference.py --scene lights imports it. Written into OUT_DIR:

  lights.gltf, lights.bin, ridges.png   the export with TANGENT attributes (export_tangents)
  lights-notangents.gltf, .bin          the same scene exported without them
  lights-scene.json, lights-notangents-scene.json   our scenes naming each file
  lights-cycles.exr (+ -variance.exr, .json)        Cycles' render (one for both files)

The scene, seen by an orthographic camera from 53 degrees above the floor:

  * floor: two 2 x 4 m quads sharing one material `ridged`, a grey Lambert surface whose normal
    map (ridges.png, 16 x 16 texels) holds slanted stripes of two tilts (8 and 20 degrees) leaning
    in two directions that each have an x and a y part, so a flipped green channel, a swapped
    tangent or a lost handedness each move the shading. The left quad's u runs along +x, the right
    quad's along -x (its uv mirrored: MikkTSpace handedness w = -1).
    Exported as a Principled BSDF with a Normal Map node; rendered as a Diffuse BSDF (Lambert)
    with the same Normal Map node (tangent space, UVMap) and the image as Non-Color, Closest.
  * wall and block: Lambert greys (Principled when exported).
  * lamps, all of radius 0 (points) or angle 0 (sun):
      point `bulb`: P watts, coloured. Cycles' radiant intensity is P / (4 pi) W/sr; the
        exporter writes P / (4 pi) * 683 cd, which our import divides by 683.
      spot `spot`: P watts, spot_size and spot_blend. The exporter writes P / (4 pi) * 683 cd with
        outerConeAngle = spot_size / 2 and innerConeAngle = outer * (1 - blend). Cycles 3.4's spot
        differs from glTF's by definition: inside the cone its intensity is P / (4 pi) times the
        cosine of the angle to the axis, and the blend is a smoothstep in that cosine over
        (1 - cos outer) * blend. So the lamp is rendered with blend 0 and a light node tree whose
        strength is ramp(angle) / cos(angle), ramp being our (and the exporter's) profile: 1 up to
        the inner angle, linear in angle to 0 at the outer one. What Cycles then renders is the
        glTF light as we read it; what is checked is the import's units, position, axis and angles.
      sun `sun`: E W/m^2 (Cycles: irradiance on a surface facing it); exported as E * 683 lux.
  * direct light only (our max_depth 1, Cycles 0 bounces), and every floor normal leaning away
    from every lamp: Cycles darkens a normal-mapped diffuse surface lit from the side its normal
    leans to, and we do not (check_no_bump_shadowing).
"""

import math

import bpy
from mathutils import Euler, Vector

NAME = "lights"
NAME_NO_TANGENTS = "lights-notangents"
WIDTH, HEIGHT = 64, 48
MAX_DEPTH = 1  # direct light only (Cycles: 0 bounces); see check_no_bump_shadowing
FLOOR_GREY = 0.5
WALL_GREY = 0.6
BLOCK_COLOUR = (0.7, 0.5, 0.3)
NORMAL_MAP = "ridges"
MAP_TEXELS = 16
# Every lamp lies in front of the floor (y <= -2) on the plane x = 0, the seam of its two halves.
BULB = {"watts": 120.0, "colour": (1.0, 0.85, 0.6), "at": (0.0, -2.3, 1.5)}
SPOT = {"watts": 400.0, "colour": (0.6, 0.8, 1.0), "at": (0.0, -2.2, 2.6),
        "aim": (0.5, 0.9, 0.0), "size_deg": 50.0, "blend": 0.35}
SUN = {"irradiance": 1.5, "colour": (1.0, 1.0, 0.9), "rotation": (0.7, 0.0, 0.0)}  # from -y


def ridge_normal(u, v):
    """Tangent-space normal at Blender uv (u, v), v up the image: slanted stripes (along
    u + v / 2, two per uv unit), 65% of each tilted 8 degrees towards (-1, 0.6), the rest 20
    degrees towards (-0.4, 1). Every normal leans towards -x and +y in tangent space."""
    s = 2.0 * (u + 0.5 * v)
    if (s - math.floor(s)) < 0.65:
        tilt, towards = math.radians(8.0), Vector((-1.0, 0.6)).normalized()
    else:
        tilt, towards = math.radians(20.0), Vector((-0.4, 1.0)).normalized()
    return (math.sin(tilt) * towards.x, math.sin(tilt) * towards.y, math.cos(tilt))


def make_normal_map(out_dir):
    n = MAP_TEXELS
    img = bpy.data.images.new(NORMAL_MAP, n, n, alpha=False, float_buffer=False)
    # Before the pixels: changing a generated image's colour space regenerates it (black).
    img.colorspace_settings.name = "Non-Color"
    flat = []
    for row in range(n):  # Blender's pixels start at the bottom row: v grows with the row
        for col in range(n):
            x, y, z = ridge_normal((col + 0.5) / n, (row + 0.5) / n)
            flat += [0.5 + 0.5 * x, 0.5 + 0.5 * y, 0.5 + 0.5 * z, 1.0]
    img.pixels = flat
    img.filepath_raw = f"{out_dir}/{NORMAL_MAP}.png"
    img.file_format = "PNG"
    img.save()
    bpy.data.images.remove(img)
    # Read back from the file, so that Cycles and the exporter see its 8-bit values.
    img = bpy.data.images.load(f"{out_dir}/{NORMAL_MAP}.png")
    img.name = NORMAL_MAP
    img.colorspace_settings.name = "Non-Color"
    return img


def normal_map_nodes(nodes, links, image, target):
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = "Closest"
    tex.extension = "REPEAT"
    nm = nodes.new("ShaderNodeNormalMap")
    nm.space = "TANGENT"
    nm.uv_map = "UVMap"
    nm.inputs["Strength"].default_value = 1.0
    links.new(tex.outputs["Color"], nm.inputs["Color"])
    links.new(nm.outputs["Normal"], target)


def aim(obj, target):
    obj.rotation_euler = (Vector(target) - obj.location).to_track_quat("-Z", "Y").to_euler()


def lamp(kind, name, **props):
    data = bpy.data.lights.new(name, kind)
    for key, value in props.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def build(out_dir, helpers):
    """The Blender scene, ready to export; returns the state set_render_materials needs."""
    principled, mesh_object = helpers["principled"], helpers["mesh_object"]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    image = make_normal_map(out_dir)

    ridged, node = principled("ridged", **{"Base Color": (FLOOR_GREY, FLOOR_GREY, FLOOR_GREY, 1.0),
                                           "Roughness": 1.0})
    normal_map_nodes(ridged.node_tree.nodes, ridged.node_tree.links, image, node.inputs["Normal"])
    wall, _ = principled("wall", **{"Base Color": (WALL_GREY, WALL_GREY, WALL_GREY, 1.0),
                                    "Roughness": 1.0})
    block, _ = principled("block", **{"Base Color": (*BLOCK_COLOUR, 1.0), "Roughness": 1.0})

    # 1 uv unit per metre; the right quad's u runs along -x (mirrored: handedness -1).
    mesh_object("floor.L", [(-2, -2, 0), (0, -2, 0), (0, 2, 0), (-2, 2, 0)], [(0, 1, 2, 3)],
                uvs=[(0, 0), (2, 0), (2, 4), (0, 4)], material=ridged)
    mesh_object("floor.R", [(0, -2, 0), (2, -2, 0), (2, 2, 0), (0, 2, 0)], [(0, 1, 2, 3)],
                uvs=[(2, 0), (0, 0), (0, 4), (2, 4)], material=ridged)
    mesh_object("wall", [(-2, 2, 0), (2, 2, 0), (2, 2, 1.6), (-2, 2, 1.6)], [(0, 3, 2, 1)],
                material=wall)
    hx, hy, hz = 0.3, 0.3, 0.4
    box_v = [(x, y, z) for z in (-hz, hz) for y in (-hy, hy) for x in (-hx, hx)]
    box_f = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    box = mesh_object("block", box_v, box_f, material=block)
    box.location = (-0.5, 0.4, hz)
    box.rotation_euler = Euler((0.0, 0.0, 0.4))

    bulb = lamp("POINT", "bulb", energy=BULB["watts"], color=BULB["colour"], shadow_soft_size=0.0)
    bulb.location = BULB["at"]
    spot = lamp("SPOT", "spot", energy=SPOT["watts"], color=SPOT["colour"], shadow_soft_size=0.0,
                spot_size=math.radians(SPOT["size_deg"]), spot_blend=SPOT["blend"])
    spot.location = SPOT["at"]
    aim(spot, SPOT["aim"])
    sun = lamp("SUN", "sun", energy=SUN["irradiance"], color=SUN["colour"], angle=0.0)
    sun.rotation_euler = Euler(SUN["rotation"])
    for data in bpy.data.lights:
        data.use_custom_distance = False  # no glTF `range`
        data.cycles.max_bounces = 1024

    cam_data = bpy.data.cameras.new("camera")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 5.4  # the film's width, in metres (sensor_fit AUTO, 4:3)
    cam_data.sensor_fit = "AUTO"
    cam_data.clip_start = 1e-3
    cam_data.clip_end = 1e4
    cam = bpy.data.objects.new("camera", cam_data)
    cam.location = (0.2, -3.5, 5.5)
    aim(cam, (0.0, 0.3, 0.4))
    scene.collection.objects.link(cam)
    scene.camera = cam

    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    scene.world = world
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    state = {"scene": scene, "image": image, "bulb": bulb, "spot": spot, "sun": sun}
    bpy.context.view_layer.update()  # world matrices for the check
    check_no_bump_shadowing(state)
    return state


def floor_normals():
    """The floor's world normals, as the 8-bit map holds them, each with the sign of x on the half
    it lies on (u along +x on the left half, -x on the right), for each texel kind."""
    out = []
    for u, v in ((0.1, 0.1), (0.45, 0.1)):  # one texel of each kind
        n = [round(255 * (0.5 + 0.5 * c)) / 255 * 2 - 1 for c in ridge_normal(u, v)]
        for sign in (1, -1):  # the left half's tangent is +x, the right half's -x
            out.append((Vector((sign * n[0], n[1], n[2])).normalized(), -sign))
    return out


def check_no_bump_shadowing(state):
    """Cycles 3.4 multiplies a Diffuse BSDF whose normal is perturbed (normal map) by a shadowing
    term in the light's direction l: with g = (Ng.l) / ((N.l) (Ng.N)), the term is 1 for g >= 1
    and g + g^2 - g^3 below; we have no such term (Lambert with the perturbed normal). It is 1
    wherever no normal leans towards the light by more than its own tilt, which the scene keeps:
    every normal leans to -x on the left half, +x on the right, and +y on both, away from every
    lamp, and there is no indirect light (it would come from the wall behind, towards which the
    normals lean). Also keeps Cycles' ensure_valid_reflection idle: the camera's view reflected
    about every normal stays well above the floor."""
    up = Vector((0.0, 0.0, 1.0))
    lamps = [(state["bulb"].location, None), (state["spot"].location, None),
              (None, state["sun"].matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0)))]
    for n, side in floor_normals():
        for i in range(11):
            for j in range(21):
                p = Vector((side * 0.2 * i, -2.0 + 0.2 * j, 0.0))
                for at, towards in lamps:
                    l = (at - p).normalized() if at is not None else towards.normalized()
                    nl = n.dot(l)
                    if nl > 0.0 and up.dot(l) / (nl * up.dot(n)) < 1.0:
                        raise RuntimeError(f"normal {tuple(n)} at {tuple(p)} leans towards a lamp")
        view = state["scene"].camera.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))
        reflected = 2.0 * n.dot(view) * n - view
        if reflected.z < 0.1:
            raise RuntimeError(f"the view reflected about {tuple(n)} grazes the floor")


def spot_angles():
    """(inner, outer) half-angles in radians, as the exporter computes them."""
    outer = math.radians(SPOT["size_deg"]) * 0.5
    return outer - outer * SPOT["blend"], outer


def glTF_profile_spot(spot):
    """Makes Cycles' spot render the glTF profile: blend 0, and a strength of ramp / cos, where
    cos is the cosine to the axis (the light-local direction's -z, from Texture Coordinate >
    Normal) that Cycles 3.4 multiplies a spot's intensity by."""
    inner, outer = spot_angles()
    data = spot.data
    data.spot_blend = 0.0
    data.use_nodes = True
    nodes, links = data.node_tree.nodes, data.node_tree.links
    emission = nodes["Emission"]

    def math_node(op, a=None, b=None, clamp=False):
        m = nodes.new("ShaderNodeMath")
        m.operation = op
        m.use_clamp = clamp
        for i, x in enumerate((a, b)):
            if isinstance(x, float):
                m.inputs[i].default_value = x
            elif x is not None:
                links.new(x, m.inputs[i])
        return m.outputs[0]

    coords = nodes.new("ShaderNodeTexCoord")
    split = nodes.new("ShaderNodeSeparateXYZ")
    links.new(coords.outputs["Normal"], split.inputs[0])
    cosine = math_node("MULTIPLY", split.outputs["Z"], -1.0)
    angle = math_node("ARCCOSINE", cosine)
    ramp = math_node("DIVIDE", math_node("SUBTRACT", outer, angle), outer - inner, clamp=True)
    links.new(math_node("DIVIDE", ramp, cosine), emission.inputs["Strength"])


def set_render_materials(state, helpers):
    replace_tree, lambert = helpers["replace_tree"], helpers["lambert"]

    def ridged(nodes, links):
        d = lambert(nodes, (FLOOR_GREY, FLOOR_GREY, FLOOR_GREY, 1))
        normal_map_nodes(nodes, links, state["image"], d.inputs["Normal"])
        return d.outputs["BSDF"]

    replace_tree(bpy.data.materials["ridged"], ridged)
    replace_tree(bpy.data.materials["wall"],
                 lambda nodes, links: lambert(nodes, (WALL_GREY, WALL_GREY, WALL_GREY, 1)).outputs["BSDF"])
    replace_tree(bpy.data.materials["block"],
                 lambda nodes, links: lambert(nodes, (*BLOCK_COLOUR, 1)).outputs["BSDF"])
    glTF_profile_spot(state["spot"])


def our_scene(gltf_name):
    """Our JSON scene for one of the two exports: the Lambert materials, the normal map read as
    glTF reads it (linear, uv origin top left), the film and the path length."""
    return {
        "format": 1,
        "gltf": {"file": gltf_name + ".gltf"},
        "film": {"width": WIDTH, "height": HEIGHT},
        "textures": {NORMAL_MAP: {"type": "image", "file": NORMAL_MAP + ".png",
                                  "color_space": "linear", "filter": "nearest", "wrap": "repeat",
                                  "uv_origin": "top_left"}},
        "materials": {
            "ridged": {"type": "diffuse", "albedo": [FLOOR_GREY] * 3,
                       "normal_map": {"texture": NORMAL_MAP}},
            "wall": {"type": "diffuse", "albedo": [WALL_GREY] * 3},
            "block": {"type": "diffuse", "albedo": list(BLOCK_COLOUR)},
        },
        "render": {"max_depth": MAX_DEPTH},
    }


def materials_rendered():
    inner, outer = spot_angles()
    return {
        "ridged": f"Diffuse BSDF roughness 0, colour {FLOOR_GREY}, Normal Map node (tangent space, "
                  "UVMap, strength 1) reading ridges.png as Non-Color, Closest interpolation",
        "wall": f"Diffuse BSDF roughness 0, colour {WALL_GREY}",
        "block": f"Diffuse BSDF roughness 0, colour {list(BLOCK_COLOUR)}",
        "lamps": {
            "bulb": f"point, {BULB['watts']} W, colour {list(BULB['colour'])}, radius 0",
            "spot": f"spot, {SPOT['watts']} W, colour {list(SPOT['colour'])}, radius 0, spot_size "
                    f"{SPOT['size_deg']} deg, exported with blend {SPOT['blend']} (inner {inner} "
                    f"rad, outer {outer} rad); rendered with blend 0 and Emission strength "
                    "clamp((outer - angle) / (outer - inner)) / cos(angle)",
            "sun": f"sun, {SUN['irradiance']} W/m^2, colour {list(SUN['colour'])}, angle 0",
        },
    }
