# Run by test_shader_nodes.py in a subprocess Blender:
#
#   blender -b --addons coherent --python node_scenes.py -- OUT_DIR CASE [CASE ...]
#
# Builds one scene per CASE: an orthographic camera sees exactly a 2x2 plane
# whose material is an Emission shader (strength 1) driven by the node graph
# under test, over a black world. Renders it at 1 sample per pixel with
# Cycles and with COHERENT to OUT_DIR/<case>_<engine>.exr. An emitter seen by
# the camera shows its emission exactly, so the two images must agree pixel
# for pixel, up to float rounding (and filtering for image lookups).
#
# Every node under test reads coordinates that are constant over a pixel:
# UV snapped to the pixel centre (Vector Math Snap + Add), so the random
# position of the one sample inside its pixel cannot change the value.

import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "blend_scenes"))
from cycles_reference import configure_cycles_reference  # noqa: E402

RES = 32
MATH_OPS = ("ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "SINE", "COSINE", "TANGENT", "ARCSINE", "ARCCOSINE",
            "ARCTANGENT", "POWER", "LOGARITHM", "MINIMUM", "MAXIMUM", "ROUND", "LESS_THAN", "GREATER_THAN",
            "MODULO", "ABSOLUTE", "ARCTAN2", "FLOOR", "CEIL", "FRACT", "SQRT", "INVERSE_SQRT", "SIGN", "EXPONENT",
            "RADIANS", "DEGREES", "SINH", "COSH", "TANH", "TRUNC", "SNAP", "WRAP", "COMPARE", "MULTIPLY_ADD",
            "PINGPONG", "SMOOTH_MIN", "SMOOTH_MAX")
VECTOR_OPS = ("ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "CROSS_PRODUCT", "PROJECT", "REFLECT", "DOT_PRODUCT",
              "DISTANCE", "LENGTH", "SCALE", "NORMALIZE", "SNAP", "FLOOR", "CEIL", "MODULO", "FRACTION",
              "ABSOLUTE", "MINIMUM", "MAXIMUM", "WRAP", "SINE", "COSINE", "TANGENT", "REFRACT", "FACEFORWARD",
              "MULTIPLY_ADD")
BLENDS = ("MIX", "DARKEN", "MULTIPLY", "BURN", "LIGHTEN", "SCREEN", "DODGE", "ADD", "OVERLAY", "SOFT_LIGHT",
          "LINEAR_LIGHT", "DIFFERENCE", "SUBTRACT", "DIVIDE", "HUE", "SATURATION", "COLOR", "VALUE")


def setup_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    plane = bpy.context.active_object
    cam_data = bpy.data.cameras.new("cam")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 2.0
    cam = bpy.data.objects.new("cam", cam_data)
    cam.location = (0.0, 0.0, 2.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    world = bpy.data.worlds.new("black")
    world.color = (0.0, 0.0, 0.0)
    scene.world = world
    r = scene.render
    r.resolution_x = r.resolution_y = RES
    r.resolution_percentage = 100
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.film_transparent = False
    scene.view_settings.view_transform = "Standard"
    configure_cycles_reference(scene, 1)
    scene.coherent.samples = 1
    material = bpy.data.materials.new("under_test")
    material.use_nodes = True
    plane.data.materials.append(material)
    return scene, plane, material


def add_sun_camera_and_grey_world(scene, camera_location, grey):
    """The whole-scene tests' and benches' lighting and view: a sun (3 W/m^2)
    from above, a camera at `camera_location` looking down the diagonal at
    the origin, and a uniform grey world."""
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.6, 0.2, 0.8)
    scene.collection.objects.link(sun)
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    cam.location = camera_location
    cam.rotation_euler = (0.95, 0.0, 0.785)
    scene.collection.objects.link(cam)
    scene.camera = cam
    world = bpy.data.worlds.new("grey")
    world.color = grey
    scene.world = world


def fresh_tree(material):
    nt = material.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    emission = nt.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 1.0
    nt.links.new(emission.outputs[0], out.inputs["Surface"])
    return nt, emission


def node(nt, kind, **props):
    n = nt.nodes.new(kind)
    for key, value in props.items():
        setattr(n, key, value)
    return n


def pixel_uv(nt, res=RES):
    """UV snapped to the centre of the pixel it is seen in."""
    coord = node(nt, "ShaderNodeTexCoord")
    snap = node(nt, "ShaderNodeVectorMath", operation="SNAP")
    snap.inputs[1].default_value = (1.0 / res, 1.0 / res, 1.0)
    nt.links.new(coord.outputs["UV"], snap.inputs[0])
    add = node(nt, "ShaderNodeVectorMath", operation="ADD")
    add.inputs[1].default_value = (0.5 / res, 0.5 / res, 0.0)
    nt.links.new(snap.outputs[0], add.inputs[0])
    return add.outputs[0]


def separate(nt, vector):
    sep = node(nt, "ShaderNodeSeparateXYZ")
    nt.links.new(vector, sep.inputs[0])
    return sep.outputs


def affine(nt, value, scale, offset):
    n = node(nt, "ShaderNodeMath", operation="MULTIPLY_ADD")
    nt.links.new(value, n.inputs[0])
    n.inputs[1].default_value = scale
    n.inputs[2].default_value = offset
    return n.outputs[0]


def combine(nt, r, g, b):
    c = node(nt, "ShaderNodeCombineXYZ")
    for k, s in enumerate((r, g, b)):
        if isinstance(s, float):
            c.inputs[k].default_value = s
        else:
            nt.links.new(s, c.inputs[k])
    return c.outputs[0]


# -- cases: (node tree) -> the socket that drives the emission colour ----------


def math_case(ops):
    def build(nt):
        u, v, _ = separate(nt, pixel_uv(nt))
        a, b = affine(nt, u, 4.0, -2.0), affine(nt, v, 3.0, -1.2)
        outs = []
        for op in ops:
            m = node(nt, "ShaderNodeMath", operation=op)
            nt.links.new(a, m.inputs[0])
            nt.links.new(b, m.inputs[1])
            m.inputs[2].default_value = 0.35
            outs.append(m.outputs[0])
        while len(outs) < 3:
            outs.append(0.0)
        return combine(nt, *outs)
    return build


def vector_case(op):
    def build(nt):
        uv = pixel_uv(nt)
        u, v, _ = separate(nt, uv)
        a = combine(nt, affine(nt, u, 4.0, -2.0), affine(nt, v, 3.0, -1.2), 0.7)
        b = combine(nt, affine(nt, v, -2.0, 1.1), 0.45, affine(nt, u, 2.5, -0.3))
        m = node(nt, "ShaderNodeVectorMath", operation=op)
        nt.links.new(a, m.inputs[0])
        nt.links.new(b, m.inputs[1])
        m.inputs[2].default_value = (0.3, -0.6, 0.9)
        m.inputs["Scale"].default_value = 0.8
        if op in ("DOT_PRODUCT", "DISTANCE", "LENGTH"):
            return m.outputs["Value"]
        return m.outputs["Vector"]
    return build


def mix_case(blend, legacy):
    def build(nt):
        uv = pixel_uv(nt)
        u, v, _ = separate(nt, uv)
        c1 = combine(nt, u, v, 0.35)
        c2 = combine(nt, affine(nt, v, -1.0, 1.0), 0.8, affine(nt, u, 0.5, 0.1))
        if legacy:
            m = node(nt, "ShaderNodeMixRGB", blend_type=blend)
            fac, a, b = m.inputs[0], m.inputs[1], m.inputs[2]
        else:
            m = node(nt, "ShaderNodeMix", data_type="RGBA", blend_type=blend)
            fac, a, b = m.inputs[0], m.inputs[6], m.inputs[7]
        nt.links.new(affine(nt, u, 0.6, 0.2), fac)
        nt.links.new(c1, a)
        nt.links.new(c2, b)
        return m.outputs[0] if legacy else m.outputs[2]
    return build


def ramp_case(interpolation):
    def build(nt):
        u, _, _ = separate(nt, pixel_uv(nt))
        ramp = node(nt, "ShaderNodeValToRGB")
        ramp.color_ramp.interpolation = interpolation
        e = ramp.color_ramp.elements
        e[0].position, e[0].color = 0.1, (0.9, 0.1, 0.2, 1.0)
        e[1].position, e[1].color = 0.8, (0.1, 0.3, 0.9, 1.0)
        mid = e.new(0.45)
        mid.color = (0.2, 0.9, 0.3, 1.0)
        nt.links.new(u, ramp.inputs[0])
        return ramp.outputs[0]
    return build


def misc_case(nt):
    """Invert, RGB to BW, Separate/Combine RGB, Mapping, Clamp and Value/RGB nodes together."""
    uv = pixel_uv(nt)
    mapping = node(nt, "ShaderNodeMapping", vector_type="POINT")
    mapping.inputs["Location"].default_value = (0.1, -0.2, 0.3)
    mapping.inputs["Rotation"].default_value = (0.3, 0.5, 0.9)
    mapping.inputs["Scale"].default_value = (1.5, 0.7, 1.2)
    nt.links.new(uv, mapping.inputs[0])
    sep = node(nt, "ShaderNodeSeparateRGB")
    nt.links.new(mapping.outputs[0], sep.inputs[0])
    invert = node(nt, "ShaderNodeInvert")
    invert.inputs[0].default_value = 0.7
    rgb = node(nt, "ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.2, 0.5, 0.8, 1.0)
    nt.links.new(rgb.outputs[0], invert.inputs[1])
    bw = node(nt, "ShaderNodeRGBToBW")
    nt.links.new(invert.outputs[0], bw.inputs[0])
    clamp = node(nt, "ShaderNodeClamp")
    clamp.inputs[1].default_value, clamp.inputs[2].default_value = 0.1, 0.6
    nt.links.new(sep.outputs[1], clamp.inputs[0])
    comb = node(nt, "ShaderNodeCombineRGB")
    nt.links.new(sep.outputs[0], comb.inputs[0])
    nt.links.new(clamp.outputs[0], comb.inputs[1])
    mul = node(nt, "ShaderNodeMath", operation="MULTIPLY")
    nt.links.new(bw.outputs[0], mul.inputs[0])
    nt.links.new(sep.outputs[2], mul.inputs[1])
    nt.links.new(mul.outputs[0], comb.inputs[2])
    return comb.outputs[0]


def checker_case(nt):
    checker = node(nt, "ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 6.0
    checker.inputs["Color1"].default_value = (0.9, 0.4, 0.1, 1.0)
    checker.inputs["Color2"].default_value = (0.1, 0.3, 0.7, 1.0)
    nt.links.new(pixel_uv(nt), checker.inputs["Vector"])
    return checker.outputs[0]


# -- procedural textures (White Noise, Noise, Voronoi, Musgrave, Wave, Gradient, Magic, Brick) ----------
#
# Each case drives the three channels with up to three outputs or node
# configurations over a point that varies across the image: x, y in [-2, 2],
# z in [0.35, 1.85] and W in [-1.1, 1.9] (scaled further by the node), so a
# 32x32 image spans several noise cells. Discontinuous outputs (cell colours,
# saw waves, brick edges) are read at pixel centres, where float rounding
# would have to land within ~1e-6 of a cell boundary to flip a pixel.


def proc_point(nt, span=4.0):
    """(vector, W) sockets varying over the image."""
    u, v, _ = separate(nt, pixel_uv(nt))
    vector = combine(nt, affine(nt, u, span, -span / 2), affine(nt, v, span, -span / 2), affine(nt, u, 1.5, 0.35))
    return vector, affine(nt, v, 3.0, -1.1)


def proc_node(nt, kind, vector=None, w=None, inputs=None, **props):
    n = node(nt, kind, **props)
    if vector is not None:
        nt.links.new(vector, n.inputs["Vector"])
    if w is not None:
        nt.links.new(w, n.inputs["W"])
    for name, value in (inputs or {}).items():
        n.inputs[name].default_value = value
    return n


def channel(nt, color, k):
    return separate(nt, color)[k]


def fac_and_color(nt, n, fac="Fac", color="Color"):
    """R: the float output, G and B: the colour's green and blue."""
    return combine(nt, n.outputs[fac], channel(nt, n.outputs[color], 1), channel(nt, n.outputs[color], 2))


def white_noise_case(dims):
    def build(nt):
        # Hashes read the bits of their input: integer lattice points, exact in both engines.
        scaled = node(nt, "ShaderNodeVectorMath", operation="MULTIPLY")
        scaled.inputs[1].default_value = (8.0, 8.0, 0.0)
        nt.links.new(pixel_uv(nt), scaled.inputs[0])
        lattice = node(nt, "ShaderNodeVectorMath", operation="FLOOR")
        nt.links.new(scaled.outputs[0], lattice.inputs[0])
        shifted = node(nt, "ShaderNodeVectorMath", operation="ADD")
        shifted.inputs[1].default_value = (-3.0, 1.0, 5.0)
        nt.links.new(lattice.outputs[0], shifted.inputs[0])
        x, y, _ = separate(nt, lattice.outputs[0])
        w = node(nt, "ShaderNodeMath", operation="MULTIPLY_ADD")
        nt.links.new(x, w.inputs[0])
        w.inputs[1].default_value = 8.0
        nt.links.new(y, w.inputs[2])
        n = proc_node(nt, "ShaderNodeTexWhiteNoise", shifted.outputs[0], w.outputs[0], noise_dimensions=dims)
        return fac_and_color(nt, n, fac="Value")
    return build


def noise_case(dims, detail, distortion):
    """Distortion amplifies rounding: the colour's seeds add offsets of 100..200 to the distorted point,
    where a float ulp is 1.5e-5, so a last-bit difference in the distortion can move a colour channel by
    ~1.5e-5 (seen on a few pixels of noise_3d), still inside the tolerance."""
    def build(nt):
        vector, w = proc_point(nt)
        n = proc_node(nt, "ShaderNodeTexNoise", vector, w, noise_dimensions=dims,
                      inputs={"Scale": 2.3, "Detail": detail, "Roughness": 0.6, "Distortion": distortion})
        return fac_and_color(nt, n)
    return build


def voronoi_case(dims, feature, metric="EUCLIDEAN", last="Position"):
    """R: Distance (Radius for N-Sphere Radius), G: colour green, B: `last` (Position x, W)."""
    def build(nt):
        vector, w = proc_point(nt)
        n = proc_node(nt, "ShaderNodeTexVoronoi", vector, w, voronoi_dimensions=dims, feature=feature,
                      distance=metric, inputs={"Scale": 1.7, "Smoothness": 0.8, "Exponent": 0.7,
                                               "Randomness": 0.85})
        first = n.outputs["Radius" if feature == "N_SPHERE_RADIUS" else "Distance"]
        third = n.outputs[last]
        if last == "Position":
            third = affine(nt, channel(nt, third, 0), 0.25, 0.5)
        elif last == "W":
            third = affine(nt, third, 0.25, 0.5)
        return combine(nt, first, channel(nt, n.outputs["Color"], 1), third)
    return build


def musgrave_case(dims, types, detail):
    """One Musgrave type per channel, mapped by 0.25 x + 0.5 into positive values."""
    def build(nt):
        vector, w = proc_point(nt)
        outs = []
        for kind in types:
            n = proc_node(nt, "ShaderNodeTexMusgrave", vector, w, musgrave_dimensions=dims, musgrave_type=kind,
                          inputs={"Scale": 1.9, "Detail": detail, "Dimension": 1.3, "Lacunarity": 2.1,
                                  "Offset": 0.9, "Gain": 1.4})
            outs.append(affine(nt, n.outputs["Fac"], 0.25, 0.5))
        while len(outs) < 3:
            outs.append(0.5)
        return combine(nt, *outs)
    return build


def wave_case(configs):
    """configs: (wave_type, direction, profile, distortion) per channel."""
    def build(nt):
        vector, _ = proc_point(nt, span=2.0)
        outs = []
        for kind, direction, profile, distortion in configs:
            props = {"wave_type": kind, "wave_profile": profile,
                     ("bands_direction" if kind == "BANDS" else "rings_direction"): direction}
            n = proc_node(nt, "ShaderNodeTexWave", vector, inputs={
                "Scale": 0.6, "Distortion": distortion, "Detail": 2.5, "Detail Scale": 1.3,
                "Detail Roughness": 0.55, "Phase Offset": 0.4}, **props)
            outs.append(n.outputs["Fac"])
        outs[-1] = channel(nt, n.outputs["Color"], 2)  # the colour output too
        return combine(nt, *outs)
    return build


def gradient_case(types):
    def build(nt):
        vector, _ = proc_point(nt, span=2.4)
        outs = [proc_node(nt, "ShaderNodeTexGradient", vector, gradient_type=t) for t in types]
        socks = [n.outputs["Fac"] for n in outs]
        socks[-1] = channel(nt, outs[-1].outputs["Color"], 2)
        while len(socks) < 3:
            socks.append(0.5)
        return combine(nt, *socks)
    return build


def magic_case(depth):
    def build(nt):
        vector, _ = proc_point(nt, span=2.0)
        n = proc_node(nt, "ShaderNodeTexMagic", vector, turbulence_depth=depth,
                      inputs={"Scale": 1.3, "Distortion": 1.7})
        return fac_and_color(nt, n)
    return build


def brick_case(offset, offset_frequency, squash, squash_frequency, mortar_smooth, bias):
    def build(nt):
        vector, _ = proc_point(nt, span=2.0)
        n = proc_node(nt, "ShaderNodeTexBrick", vector, offset=offset, offset_frequency=offset_frequency,
                      squash=squash, squash_frequency=squash_frequency, inputs={
                          "Color1": (0.9, 0.3, 0.2, 1.0), "Color2": (0.2, 0.6, 0.9, 1.0),
                          "Mortar": (0.05, 0.1, 0.0, 1.0), "Scale": 2.7, "Mortar Size": 0.06,
                          "Mortar Smooth": mortar_smooth, "Bias": bias, "Brick Width": 0.55, "Row Height": 0.23})
        color = n.outputs["Color"]
        return combine(nt, channel(nt, color, 0), n.outputs["Fac"], channel(nt, color, 2))
    return build


def procedural_cases():
    c = {}
    for dims in ("1D", "2D", "3D", "4D"):
        d = dims.lower()
        c[f"white_noise_{d}"] = white_noise_case(dims)
    c["noise_1d"] = noise_case("1D", 3.5, 0.8)
    c["noise_2d"] = noise_case("2D", 2.0, 0.0)
    c["noise_3d"] = noise_case("3D", 2.0, 1.3)
    c["noise_4d"] = noise_case("4D", 1.7, 0.5)
    # Every feature in every dimension; the metrics on F1 (3D), F2 and Smooth F1.
    metric_of = {"1D": "EUCLIDEAN", "2D": "MANHATTAN", "3D": "CHEBYCHEV", "4D": "MINKOWSKI"}
    for dims in ("1D", "2D", "3D", "4D"):
        d = dims.lower()
        last = "W" if dims in ("1D", "4D") else "Position"
        c[f"voronoi_{d}_f1"] = voronoi_case(dims, "F1", last=last)
        c[f"voronoi_{d}_f2_{metric_of[dims].lower()}"] = voronoi_case(dims, "F2", metric_of[dims], last)
        c[f"voronoi_{d}_smooth_f1"] = voronoi_case(dims, "SMOOTH_F1", "MINKOWSKI" if dims == "2D" else "EUCLIDEAN",
                                                  last)
        c[f"voronoi_{d}_edge"] = voronoi_case(dims, "DISTANCE_TO_EDGE", last=last)
        c[f"voronoi_{d}_radius"] = voronoi_case(dims, "N_SPHERE_RADIUS", last=last)
    for metric in ("MANHATTAN", "CHEBYCHEV", "MINKOWSKI"):
        c[f"voronoi_3d_f1_{metric.lower()}"] = voronoi_case("3D", "F1", metric)
    c["voronoi_4d_smooth_f1_manhattan"] = voronoi_case("4D", "SMOOTH_F1", "MANHATTAN", "W")
    types = ("FBM", "MULTIFRACTAL", "HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL", "HETERO_TERRAIN")
    for k, dims in enumerate(("1D", "2D", "3D", "4D")):
        # Rotate through the types so each dimension sees three of them and each type two dimensions.
        chosen = tuple(types[(k * 3 + j) % 5] for j in range(3))
        c[f"musgrave_{dims.lower()}"] = musgrave_case(dims, chosen, 3.5 if k % 2 else 2.0)
    c["musgrave_3d_all_b"] = musgrave_case("3D", ("HETERO_TERRAIN", "RIDGED_MULTIFRACTAL", "HYBRID_MULTIFRACTAL"),
                                           2.6)
    c["wave_bands"] = wave_case((("BANDS", "X", "SIN", 0.0), ("BANDS", "Y", "SAW", 0.0),
                                 ("BANDS", "DIAGONAL", "TRI", 0.0)))
    c["wave_bands_z_distorted"] = wave_case((("BANDS", "Z", "SIN", 3.0), ("BANDS", "DIAGONAL", "SAW", 1.5),
                                             ("BANDS", "X", "TRI", 2.0)))
    c["wave_rings"] = wave_case((("RINGS", "X", "SAW", 0.0), ("RINGS", "Y", "TRI", 0.0), ("RINGS", "Z", "SIN", 0.0)))
    c["wave_rings_spherical"] = wave_case((("RINGS", "SPHERICAL", "SIN", 2.0), ("RINGS", "SPHERICAL", "TRI", 0.0),
                                           ("RINGS", "SPHERICAL", "SAW", 1.0)))
    c["gradient_a"] = gradient_case(("LINEAR", "QUADRATIC", "EASING"))
    c["gradient_b"] = gradient_case(("DIAGONAL", "RADIAL", "QUADRATIC_SPHERE"))
    c["gradient_c"] = gradient_case(("SPHERICAL", "LINEAR"))
    for depth in (0, 1, 4, 10):
        c[f"magic_depth{depth}"] = magic_case(depth)
    c["brick"] = brick_case(0.5, 2, 1.0, 1, 0.0, 0.0)
    c["brick_offset_squash_smooth"] = brick_case(0.3, 3, 0.6, 2, 0.5, 0.2)
    return c


def make_image(name, width, height, alpha=False, is_float=True, colorspace="Non-Color"):
    """A deterministic RGBA test pattern held only inside Blender (a generated image)."""
    image = bpy.data.images.new(name, width, height, alpha=alpha, float_buffer=is_float)
    image.colorspace_settings.name = colorspace  # before the pixels: changing it regenerates the image
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    rng = np.random.default_rng(7)
    pixels = np.stack([x / (width - 1), y / (height - 1), rng.random((height, width), dtype=np.float32),
                       0.25 + 0.75 * rng.random((height, width), dtype=np.float32) if alpha
                       else np.ones((height, width), np.float32)], axis=-1)
    image.pixels.foreach_set(pixels.ravel())
    image.update()
    return image


def image_case(interpolation, extension, res_uv=RES, colorspace="Non-Color", is_float=True, scale=1.0,
               alpha_out=False, alpha_mode="STRAIGHT", with_alpha=None):
    def build(nt):
        tex = node(nt, "ShaderNodeTexImage", interpolation=interpolation, extension=extension)
        tex.image = make_image(f"pattern_{interpolation}_{extension}_{colorspace}_{is_float}_{alpha_mode}", 8, 8,
                               alpha=alpha_out if with_alpha is None else with_alpha, is_float=is_float,
                               colorspace=colorspace)
        tex.image.alpha_mode = alpha_mode
        uv = pixel_uv(nt, res_uv)
        if scale != 1.0:
            mapping = node(nt, "ShaderNodeMapping", vector_type="POINT")
            mapping.inputs["Scale"].default_value = (scale, scale, 1.0)
            mapping.inputs["Location"].default_value = (-0.4, -0.3, 0.0)
            nt.links.new(uv, mapping.inputs[0])
            uv = mapping.outputs[0]
        nt.links.new(uv, tex.inputs["Vector"])
        if alpha_out:
            mul = node(nt, "ShaderNodeVectorMath", operation="SCALE")
            nt.links.new(tex.outputs["Color"], mul.inputs[0])
            nt.links.new(tex.outputs["Alpha"], mul.inputs["Scale"])
            return mul.outputs[0]
        return tex.outputs["Color"]
    return build


def snapped(nt, vector, step):
    snap = node(nt, "ShaderNodeVectorMath", operation="SNAP")
    snap.inputs[1].default_value = (step, step, step)
    nt.links.new(vector, snap.inputs[0])
    return snap.outputs[0]


def texcoord_case(nt):
    """Generated, Object and Normal outputs of Texture Coordinate and a UV Map node, snapped per pixel."""
    coord = node(nt, "ShaderNodeTexCoord")
    uvmap = node(nt, "ShaderNodeUVMap", uv_map="UVMap")
    gen_x = separate(nt, snapped(nt, coord.outputs["Generated"], 1.0 / RES))[0]
    obj_y = separate(nt, snapped(nt, coord.outputs["Object"], 2.0 / RES))[1]
    nrm_z = separate(nt, coord.outputs["Normal"])[2]
    uv_x = separate(nt, snapped(nt, uvmap.outputs["UV"], 1.0 / RES))[0]
    blue = node(nt, "ShaderNodeMath", operation="MULTIPLY_ADD")
    nt.links.new(uv_x, blue.inputs[0])
    blue.inputs[1].default_value = 0.5
    nt.links.new(nrm_z, blue.inputs[2])
    return combine(nt, gen_x, affine(nt, obj_y, 0.5, 0.5), blue.outputs[0])


def group_case(nt):
    """A nested node group: inner group scales, outer adds; plus a reroute and a muted node."""
    inner = bpy.data.node_groups.new("inner", "ShaderNodeTree")
    inner.inputs.new("NodeSocketFloat", "x")
    inner.outputs.new("NodeSocketFloat", "y")
    gi, go = inner.nodes.new("NodeGroupInput"), inner.nodes.new("NodeGroupOutput")
    m = inner.nodes.new("ShaderNodeMath")
    m.operation = "MULTIPLY"
    m.inputs[1].default_value = 0.5
    inner.links.new(gi.outputs[0], m.inputs[0])
    inner.links.new(m.outputs[0], go.inputs[0])
    outer = bpy.data.node_groups.new("outer", "ShaderNodeTree")
    outer.inputs.new("NodeSocketFloat", "x")
    outer.outputs.new("NodeSocketFloat", "y")
    gi, go = outer.nodes.new("NodeGroupInput"), outer.nodes.new("NodeGroupOutput")
    g = outer.nodes.new("ShaderNodeGroup")
    g.node_tree = inner
    add = outer.nodes.new("ShaderNodeMath")
    add.inputs[1].default_value = 0.25
    outer.links.new(gi.outputs[0], g.inputs[0])
    outer.links.new(g.outputs[0], add.inputs[0])
    outer.links.new(add.outputs[0], go.inputs[0])
    u, v, _ = separate(nt, pixel_uv(nt))
    top = node(nt, "ShaderNodeGroup")
    top.node_tree = outer
    reroute = node(nt, "NodeReroute")
    nt.links.new(u, reroute.inputs[0])
    nt.links.new(reroute.outputs[0], top.inputs[0])
    muted = node(nt, "ShaderNodeMath", operation="SINE")
    muted.mute = True
    nt.links.new(v, muted.inputs[0])
    return combine(nt, top.outputs[0], muted.outputs[0], 0.5)


def normal_map_case(space):
    """Diffuse plane, normal from an image through a Normal Map node, lit by a sun (direct light only).

    Flat plane, constant tangents, pixel-snapped normal texels, a sun of zero
    angle and no bounces: every pixel's radiance is deterministic.
    """
    def build(nt):
        return ("normal_map", space)
    return build


def build_normal_map(scene, material, space):
    nt = material.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    diffuse = node(nt, "ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.8, 0.7, 0.6, 1.0)
    nt.links.new(diffuse.outputs[0], out.inputs["Surface"])
    tex = node(nt, "ShaderNodeTexImage", interpolation="Closest")
    image = bpy.data.images.new(f"normals_{space}", 8, 8, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    rng = np.random.default_rng(3)
    xy = rng.uniform(-0.45, 0.45, (8, 8, 2)).astype(np.float32)
    z = np.sqrt(1.0 - (xy ** 2).sum(axis=-1, keepdims=True))
    n = np.concatenate([xy, z], axis=-1) * 0.5 + 0.5
    image.pixels.foreach_set(np.concatenate([n, np.ones((8, 8, 1), np.float32)], axis=-1).ravel())
    tex.image = image
    nt.links.new(pixel_uv(nt), tex.inputs["Vector"])
    nmap = node(nt, "ShaderNodeNormalMap", space=space)
    nmap.inputs["Strength"].default_value = 0.8
    nt.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs[0], diffuse.inputs["Normal"])
    if "sun" not in bpy.data.objects:
        sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
        sun.data.energy = 2.0
        sun.data.angle = 0.0  # a point-like sun: deterministic direct light
        sun.rotation_euler = (0.3, 0.2, 0.0)
        scene.collection.objects.link(sun)
    scene.cycles.max_bounces = 0
    scene.coherent.max_bounces = 0


# -- Colour adjustments, inputs and bump ----------------------------------------------


def uv_color(nt, lo=0.0, hi=1.0, blue=0.35):
    """(u, v, blue) per pixel, u and v mapped to [lo, hi]."""
    u, v, _ = separate(nt, pixel_uv(nt))
    return combine(nt, affine(nt, u, hi - lo, lo), affine(nt, v, hi - lo, lo), blue), u, v


def set_curve(curve, points):
    """Replaces a curve's points by `points` [(x, y), ...] (at least two)."""
    while len(curve.points) > 2:
        curve.points.remove(curve.points[-1])
    curve.points[0].location, curve.points[1].location = points[0], points[1]
    for x, y in points[2:]:
        curve.points.new(x, y)


def rgb_curves_case(extend, lo=-0.2, hi=1.2):
    def build(nt):
        color, u, _ = uv_color(nt, lo, hi)
        n = node(nt, "ShaderNodeRGBCurve")
        m = n.mapping
        m.extend = extend
        set_curve(m.curves[3], [(0.0, 0.1), (0.4, 0.55), (1.0, 0.9)])  # combined
        set_curve(m.curves[0], [(0.1, 0.0), (0.6, 0.8), (1.0, 1.0)])
        set_curve(m.curves[1], [(0.0, 0.2), (0.3, 0.1), (0.9, 1.0)])
        set_curve(m.curves[2], [(0.0, 1.0), (1.0, 0.0)])
        m.update()
        n.inputs["Fac"].default_value = 0.85
        nt.links.new(color, n.inputs["Color"])
        return n.outputs[0]
    return build


def vector_curves_case(nt):
    vector, _, _ = uv_color(nt, -1.3, 1.3, blue=-0.4)
    n = node(nt, "ShaderNodeVectorCurve")
    m = n.mapping
    m.extend = "EXTRAPOLATED"
    set_curve(m.curves[0], [(-1.0, -0.5), (0.2, 0.6), (1.0, 1.0)])
    set_curve(m.curves[1], [(-1.0, 1.0), (1.0, -1.0)])
    set_curve(m.curves[2], [(-0.5, 0.3), (0.8, 0.9)])
    m.update()
    nt.links.new(vector, n.inputs["Vector"])
    return vector_math(nt, "ABSOLUTE", n.outputs[0])


def float_curve_case(nt):
    _, u, v = uv_color(nt)
    n = node(nt, "ShaderNodeFloatCurve")
    m = n.mapping
    set_curve(m.curves[0], [(0.2, 0.1), (0.5, 0.9), (0.9, 0.4)])
    m.update()
    nt.links.new(affine(nt, u, 1.4, -0.2), n.inputs["Value"])
    nt.links.new(v, n.inputs["Factor"])
    return combine(nt, n.outputs[0], v, 0.5)


def vector_math(nt, op, a, b=None):
    m = node(nt, "ShaderNodeVectorMath", operation=op)
    nt.links.new(a, m.inputs[0])
    if b is not None:
        nt.links.new(b, m.inputs[1])
    return m.outputs[0]


def hsv_case(nt):
    color, u, v = uv_color(nt, 0.05, 0.95)
    n = node(nt, "ShaderNodeHueSaturation")
    nt.links.new(affine(nt, u, 0.8, 0.1), n.inputs["Hue"])
    nt.links.new(affine(nt, v, 2.0, 0.0), n.inputs["Saturation"])
    n.inputs["Value"].default_value = 1.3
    n.inputs["Fac"].default_value = 0.9
    nt.links.new(color, n.inputs["Color"])
    return n.outputs[0]


def gamma_contrast_case(nt):
    color, u, v = uv_color(nt, -0.1, 1.1)
    gamma = node(nt, "ShaderNodeGamma")
    nt.links.new(color, gamma.inputs["Color"])
    nt.links.new(affine(nt, v, 2.5, 0.2), gamma.inputs["Gamma"])
    bc = node(nt, "ShaderNodeBrightContrast")
    nt.links.new(gamma.outputs[0], bc.inputs["Color"])
    nt.links.new(affine(nt, u, 0.6, -0.3), bc.inputs["Bright"])
    bc.inputs["Contrast"].default_value = 0.7
    return bc.outputs[0]


def map_range_case(kind):
    """Float Map Range three ways (clamped, reversed source, reversed target) and the vector one."""
    def build(nt):
        color, u, v = uv_color(nt, -0.3, 1.3)
        outs = []
        for lo, hi, to_lo, to_hi, clamp in ((0.1, 0.8, 0.2, 0.9, True), (0.9, 0.2, 0.0, 1.0, False),
                                            (0.0, 1.0, 1.0, 0.1, True)):
            n = node(nt, "ShaderNodeMapRange", data_type="FLOAT", interpolation_type=kind, clamp=clamp)
            nt.links.new(u if len(outs) != 1 else v, n.inputs[0])
            for k, x in zip((1, 2, 3, 4), (lo, hi, to_lo, to_hi)):
                n.inputs[k].default_value = x
            n.inputs[5].default_value = 3.0
            outs.append(n.outputs[0])
        vec = node(nt, "ShaderNodeMapRange", data_type="FLOAT_VECTOR", interpolation_type=kind, clamp=True)
        nt.links.new(color, vec.inputs[6])
        vec.inputs[7].default_value = (0.0, 0.9, 0.1)
        vec.inputs[8].default_value = (1.0, 0.1, 0.1)  # z: an empty source range
        vec.inputs[9].default_value = (0.1, 0.0, 0.2)
        vec.inputs[10].default_value = (0.9, 1.0, 0.6)
        vec.inputs[11].default_value = (4.0, 2.0, 3.0)
        mixed = node(nt, "ShaderNodeMix", data_type="VECTOR")
        mixed.inputs[0].default_value = 0.5
        nt.links.new(combine(nt, *outs), mixed.inputs[4])
        nt.links.new(vec.outputs[1], mixed.inputs[5])
        return mixed.outputs[1]
    return build


def hsv_convert_case(nt):
    """Separate/Combine HSV (legacy) and Separate/Combine Color in HSV and HSL modes."""
    color, u, v = uv_color(nt, 0.0, 1.0, blue=0.6)
    sep = node(nt, "ShaderNodeSeparateHSV")
    nt.links.new(color, sep.inputs[0])
    comb = node(nt, "ShaderNodeCombineHSV")
    nt.links.new(affine(nt, sep.outputs[0], 1.0, 0.3), comb.inputs[0])  # hue past 1 wraps
    nt.links.new(sep.outputs[1], comb.inputs[1])
    nt.links.new(affine(nt, sep.outputs[2], 0.8, 0.0), comb.inputs[2])
    sep_hsl = node(nt, "ShaderNodeSeparateColor", mode="HSL")
    nt.links.new(comb.outputs[0], sep_hsl.inputs[0])
    comb_hsl = node(nt, "ShaderNodeCombineColor", mode="HSL")
    nt.links.new(affine(nt, sep_hsl.outputs[0], 1.0, 0.1), comb_hsl.inputs[0])
    nt.links.new(sep_hsl.outputs[1], comb_hsl.inputs[1])
    nt.links.new(affine(nt, sep_hsl.outputs[2], 1.2, 0.0), comb_hsl.inputs[2])
    return comb_hsl.outputs[0]


def uv_normal(nt):
    """A unit normal per pixel, tilted by the pixel's UV."""
    u, v, _ = separate(nt, pixel_uv(nt))
    return vector_math(nt, "NORMALIZE", combine(nt, affine(nt, u, 1.6, -0.8), affine(nt, v, 1.6, -0.8), 0.5))


def fresnel_case(nt):
    """IOR per pixel at the default normal (facing the camera), and a tilted Normal input."""
    u, v, _ = separate(nt, pixel_uv(nt))
    normal = uv_normal(nt)
    outs = []
    for ior, linked in ((affine(nt, u, 2.0, 0.9), False), (None, True), (affine(nt, v, 1.5, 1.05), True)):
        n = node(nt, "ShaderNodeFresnel")
        if ior is None:
            n.inputs["IOR"].default_value = 1.45
        else:
            nt.links.new(ior, n.inputs["IOR"])
        if linked:
            nt.links.new(normal, n.inputs["Normal"])
        outs.append(n.outputs[0])
    return combine(nt, *outs)


def layer_weight_case(nt):
    u, v, _ = separate(nt, pixel_uv(nt))
    normal = uv_normal(nt)
    a = node(nt, "ShaderNodeLayerWeight")
    nt.links.new(u, a.inputs["Blend"])
    nt.links.new(normal, a.inputs["Normal"])
    b = node(nt, "ShaderNodeLayerWeight")
    b.inputs["Blend"].default_value = 0.5  # Facing's pow is skipped at exactly 0.5
    nt.links.new(normal, b.inputs["Normal"])
    c = node(nt, "ShaderNodeLayerWeight")  # default normal: facing the camera
    nt.links.new(v, c.inputs["Blend"])
    add = node(nt, "ShaderNodeMath", operation="ADD")
    nt.links.new(b.outputs["Facing"], add.inputs[0])
    nt.links.new(c.outputs["Fresnel"], add.inputs[1])
    return combine(nt, a.outputs["Fresnel"], a.outputs["Facing"], add.outputs[0])


def geometry_case(nt):
    """Position (pixel-snapped), Normal, True Normal, Incoming and Backfacing of a (tilted) plane."""
    geo = node(nt, "ShaderNodeNewGeometry")
    px, py, _ = separate(nt, snapped(nt, geo.outputs["Position"], 2.0 / RES))
    dots = []
    for name, weights in (("Normal", (0.3, -0.2, 0.25)), ("True Normal", (-0.1, 0.2, 0.15)),
                          ("Incoming", (0.05, 0.1, 0.2))):
        d = node(nt, "ShaderNodeVectorMath", operation="DOT_PRODUCT")
        nt.links.new(geo.outputs[name], d.inputs[0])
        d.inputs[1].default_value = weights
        dots.append(d.outputs["Value"])
    total = dots[0]
    for term in dots[1:] + [geo.outputs["Backfacing"]]:
        add = node(nt, "ShaderNodeMath", operation="ADD")
        nt.links.new(total, add.inputs[0])
        nt.links.new(term, add.inputs[1])
        total = add.outputs[0]
    return combine(nt, affine(nt, px, 0.4, 0.5), affine(nt, py, 0.4, 0.5), affine(nt, total, 0.5, 0.4))


def node_abs(nt, x):
    n = node(nt, "ShaderNodeMath", operation="ABSOLUTE")
    nt.links.new(x, n.inputs[0])
    return n.outputs[0]


def geometry_smooth_case(nt):
    """Parametric and Tangent, which vary inside a pixel (compared within SMOOTH_TOLERANCE)."""
    geo = node(nt, "ShaderNodeNewGeometry")
    position = snapped(nt, geo.outputs["Position"], 2.0 / RES)
    # Pixels on the diagonal where the plane's two triangles meet (x = y)
    # jump from one triangle's barycentrics to the other's: masked out.
    px, py, _ = separate(nt, position)
    gap = node(nt, "ShaderNodeMath", operation="SUBTRACT")
    nt.links.new(px, gap.inputs[0])
    nt.links.new(py, gap.inputs[1])
    off_diagonal = node(nt, "ShaderNodeMath", operation="GREATER_THAN")
    nt.links.new(node_abs(nt, gap.outputs[0]), off_diagonal.inputs[0])
    off_diagonal.inputs[1].default_value = 0.03
    parametric = node(nt, "ShaderNodeVectorMath", operation="SCALE")
    nt.links.new(geo.outputs["Parametric"], parametric.inputs[0])
    nt.links.new(off_diagonal.outputs[0], parametric.inputs["Scale"])
    bx, by, _ = separate(nt, parametric.outputs[0])
    tx, _, _ = separate(nt, geo.outputs["Tangent"])
    # Near the tangent's pole (the plane's centre) it turns fast: masked out.
    radius = node(nt, "ShaderNodeVectorMath", operation="LENGTH")
    nt.links.new(position, radius.inputs[0])
    mask = node(nt, "ShaderNodeMath", operation="GREATER_THAN")
    nt.links.new(radius.outputs["Value"], mask.inputs[0])
    mask.inputs[1].default_value = 0.5
    blue = node(nt, "ShaderNodeMath", operation="MULTIPLY")
    nt.links.new(affine(nt, tx, 0.5, 0.5), blue.inputs[0])
    nt.links.new(mask.outputs[0], blue.inputs[1])
    return combine(nt, bx, by, blue.outputs[0])


# Cases whose value varies inside a pixel: the largest difference two points
# of one pixel can make (gradient x pixel diagonal), instead of float rounding.
SMOOTH_TOLERANCE = {"geometry_smooth": 0.1, "bump_wavy": 0.05}


def flipped(build):
    """A case seen from the plane's back (rotated half a turn about x)."""
    def wrapped(nt):
        return ("custom", build, _flip_plane)
    return wrapped


def _flip_plane(scene, plane):
    plane.rotation_euler = (3.14159265, 0.0, 0.0)
    return lambda: setattr(plane, "rotation_euler", (0.0, 0.0, 0.0))


def light_path_material(nt):
    """Emission packing Light Path outputs: R ray kinds, G reflect/transmit/shadow, B depths and length."""
    lp = node(nt, "ShaderNodeLightPath")
    o = lp.outputs

    def weighted(terms, offset):
        total = offset
        for socket, w in terms:
            m = node(nt, "ShaderNodeMath", operation="MULTIPLY_ADD")
            nt.links.new(socket, m.inputs[0])
            m.inputs[1].default_value = w
            if isinstance(total, float):
                m.inputs[2].default_value = total
            else:
                nt.links.new(total, m.inputs[2])
            total = m.outputs[0]
        return total
    cam_length = node(nt, "ShaderNodeMath", operation="MULTIPLY")
    nt.links.new(o["Is Camera Ray"], cam_length.inputs[0])
    nt.links.new(o["Ray Length"], cam_length.inputs[1])
    r = weighted([(o["Is Camera Ray"], 0.5), (o["Is Glossy Ray"], 0.25), (o["Is Singular Ray"], 0.125),
                  (o["Is Diffuse Ray"], 0.0625)], 0.01)
    g = weighted([(o["Is Reflection Ray"], 0.5), (o["Is Transmission Ray"], 0.25), (o["Is Shadow Ray"], 0.125)],
                 0.01)
    b = weighted([(o["Ray Depth"], 0.2), (o["Glossy Depth"], 0.1), (o["Diffuse Depth"], 0.05),
                  (o["Transmission Depth"], 0.025), (o["Transparent Depth"], 0.3), (cam_length.outputs[0], 0.05)],
                 0.01)
    return combine(nt, r, g, b)


def light_path_case(nt):
    """The emitter seen directly (camera rays) and in a sharp mirror (singular glossy reflection)."""
    return ("custom", light_path_material, _mirror_setup)


def _mirror_setup(scene, plane):
    """Plane at x < 0 seen directly; a 45-degree mirror at x > 0 shows a second emitter at x = 3."""
    plane.scale = (0.5, 1.0, 1.0)
    plane.location = (-0.5, 0.0, 0.0)
    bpy.ops.mesh.primitive_plane_add(size=2.0, location=(0.5, 0.0, 0.0), rotation=(0.0, 0.7853982, 0.0))
    mirror = bpy.context.active_object
    mirror.scale = (0.375 * 2 ** 0.5, 1.0, 1.0)  # spans x in [0.125, 0.875]: edges on pixel edges
    glossy = bpy.data.materials.new("mirror")
    glossy.use_nodes = True
    gnt = glossy.node_tree
    gnt.nodes.clear()
    out = gnt.nodes.new("ShaderNodeOutputMaterial")
    bsdf = gnt.nodes.new("ShaderNodeBsdfGlossy")
    bsdf.inputs["Roughness"].default_value = 0.0
    bsdf.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    gnt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    mirror.data.materials.append(glossy)
    bpy.ops.mesh.primitive_plane_add(size=3.0, location=(3.0, 0.0, 0.0), rotation=(0.0, -1.5707963, 0.0))
    wall = bpy.context.active_object
    wall.data.materials.append(plane.material_slots[0].material)
    bounces = scene.cycles.max_bounces, scene.coherent.max_bounces
    scene.cycles.max_bounces = scene.coherent.max_bounces = 4

    def restore():
        for ob in (mirror, wall):
            bpy.data.objects.remove(ob)
        plane.scale, plane.location = (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)
        scene.cycles.max_bounces, scene.coherent.max_bounces = bounces
    return restore


def attribute_material(nt):
    """Color Attribute (float, corner), Attribute of a byte colour (colour x alpha) and of a face float (Fac)."""
    col = node(nt, "ShaderNodeVertexColor", layer_name="col_float")
    byte = node(nt, "ShaderNodeAttribute", attribute_name="col_byte")
    weight = node(nt, "ShaderNodeAttribute", attribute_name="weight")
    render = node(nt, "ShaderNodeVertexColor", layer_name="")  # the render colour attribute: col_byte
    scaled = node(nt, "ShaderNodeVectorMath", operation="SCALE")
    nt.links.new(byte.outputs["Color"], scaled.inputs[0])
    nt.links.new(byte.outputs["Alpha"], scaled.inputs["Scale"])
    total = vector_math(nt, "ADD", col.outputs["Color"], scaled.outputs[0])
    fac = node(nt, "ShaderNodeVectorMath", operation="SCALE")
    nt.links.new(render.outputs["Color"], fac.inputs[0])
    nt.links.new(weight.outputs["Fac"], fac.inputs["Scale"])
    return vector_math(nt, "ADD", vector_math(nt, "SCALE", total), fac.outputs[0])


def attribute_case(nt):
    return ("custom", attribute_material, _attribute_grid)


def _attribute_grid(scene, plane):
    """An 8 x 8 grid over the plane's square, every face one colour (4 x 4 pixels each)."""
    k = 8
    xs = np.linspace(-1.0, 1.0, k + 1)
    verts = [(x, y, 0.0) for y in xs for x in xs]
    faces = [(j * (k + 1) + i, j * (k + 1) + i + 1, (j + 1) * (k + 1) + i + 1, (j + 1) * (k + 1) + i)
             for j in range(k) for i in range(k)]
    mesh = bpy.data.meshes.new("grid")
    mesh.from_pydata(verts, [], faces)
    rng = np.random.default_rng(11)
    face_rgba = rng.random((k * k, 4), dtype=np.float32)
    corner = np.repeat(face_rgba, 4, axis=0)
    mesh.color_attributes.new("col_float", "FLOAT_COLOR", "CORNER").data.foreach_set("color", corner.ravel())
    byte = mesh.color_attributes.new("col_byte", "BYTE_COLOR", "CORNER")
    byte.data.foreach_set("color_srgb", corner[:, [2, 0, 1, 3]].ravel())
    mesh.color_attributes.render_color_index = 1
    mesh.attributes.new("weight", "FLOAT", "FACE").data.foreach_set("value", face_rgba[:, 0] * 2.0)
    grid = bpy.data.objects.new("grid", mesh)
    scene.collection.objects.link(grid)
    mesh.materials.append(plane.material_slots[0].material)
    plane.hide_render = True

    def restore():
        bpy.data.objects.remove(grid)
        plane.hide_render = False
    return restore


def bump_case(height, invert=False, strength=1.0, distance=1.0):
    """A diffuse plane lit by a point-like sun (direct light only), its normal from a Bump node."""
    def build(nt):
        return ("lit", lambda scene, material: _build_bump(scene, material, height, invert, strength, distance))
    return build


def _build_bump(scene, material, height, invert, strength, distance):
    nt = material.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    diffuse = node(nt, "ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.8, 0.7, 0.6, 1.0)
    nt.links.new(diffuse.outputs[0], out.inputs["Surface"])
    bump = node(nt, "ShaderNodeBump", invert=invert)
    bump.inputs["Strength"].default_value = strength
    bump.inputs["Distance"].default_value = distance
    nt.links.new(height(nt), bump.inputs["Height"])
    nt.links.new(bump.outputs[0], diffuse.inputs["Normal"])
    if "sun" not in bpy.data.objects:
        sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
        sun.data.energy = 2.0
        sun.data.angle = 0.0
        sun.rotation_euler = (0.3, 0.2, 0.0)
        scene.collection.objects.link(sun)
    scene.cycles.max_bounces = 0
    scene.coherent.max_bounces = 0


def position_height(nt):
    """A plane's height rising along (3, -2): linear, so its finite differences are exact."""
    d = node(nt, "ShaderNodeVectorMath", operation="DOT_PRODUCT")
    nt.links.new(node(nt, "ShaderNodeNewGeometry").outputs["Position"], d.inputs[0])
    d.inputs[1].default_value = (3.0, -2.0, 0.0)
    return d.outputs["Value"]


def uv_height(nt):
    u, v, _ = separate(nt, node(nt, "ShaderNodeTexCoord").outputs["UV"])
    m = node(nt, "ShaderNodeMath", operation="SUBTRACT")
    nt.links.new(affine(nt, u, 8.0, 0.0), m.inputs[0])
    nt.links.new(affine(nt, v, 5.0, 0.0), m.inputs[1])
    return m.outputs[0]


def wavy_height(nt):
    """sin(4 x) + y^2: curved, so the normal changes inside a pixel (SMOOTH_TOLERANCE)."""
    x, y, _ = separate(nt, node(nt, "ShaderNodeTexCoord").outputs["Object"])
    s = node(nt, "ShaderNodeMath", operation="SINE")
    nt.links.new(affine(nt, x, 4.0, 0.0), s.inputs[0])
    sq = node(nt, "ShaderNodeMath", operation="MULTIPLY")
    nt.links.new(y, sq.inputs[0])
    nt.links.new(y, sq.inputs[1])
    add = node(nt, "ShaderNodeMath", operation="ADD")
    nt.links.new(s.outputs[0], add.inputs[0])
    nt.links.new(sq.outputs[0], add.inputs[1])
    return add.outputs[0]


def adjust_cases():
    c = {"curves_rgb_extrapolated": rgb_curves_case("EXTRAPOLATED"),
         "curves_rgb_horizontal": rgb_curves_case("HORIZONTAL"),
         "curves_vector": vector_curves_case,
         "curves_float": float_curve_case,
         "hue_saturation": hsv_case,
         "gamma_bright_contrast": gamma_contrast_case,
         "hsv_hsl_convert": hsv_convert_case,
         "fresnel": fresnel_case,
         "fresnel_back": flipped(fresnel_case),
         "layer_weight": layer_weight_case,
         "layer_weight_back": flipped(layer_weight_case),
         "geometry": geometry_case,
         "geometry_back": flipped(geometry_case),
         "geometry_smooth": geometry_smooth_case,
         "light_path": light_path_case,
         "attributes": attribute_case,
         "bump_position": bump_case(position_height, distance=0.3),
         "bump_uv_inverted": bump_case(uv_height, invert=True, strength=0.7, distance=0.05),
         "bump_wavy": bump_case(wavy_height, distance=0.2)}
    for kind in ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP"):
        c[f"map_range_{kind.lower()}"] = map_range_case(kind)
    return c


def cases():
    c = {}
    for i in range(0, len(MATH_OPS), 3):
        c[f"math_{i // 3:02d}"] = math_case(MATH_OPS[i:i + 3])
    for op in VECTOR_OPS:
        c[f"vector_{op.lower()}"] = vector_case(op)
    for blend in BLENDS:
        c[f"mix_{blend.lower()}"] = mix_case(blend, legacy=False)
    c["mixrgb_overlay"] = mix_case("OVERLAY", legacy=True)
    for interp in ("LINEAR", "CONSTANT", "EASE", "B_SPLINE"):
        c[f"ramp_{interp.lower()}"] = ramp_case(interp)
    c["misc"] = misc_case
    c["checker"] = checker_case
    c["group"] = group_case
    c["image_closest_repeat"] = image_case("Closest", "REPEAT", scale=1.7)
    c["image_closest_extend"] = image_case("Closest", "EXTEND", scale=1.7)
    c["image_closest_clip"] = image_case("Closest", "CLIP", scale=1.7)
    c["image_linear"] = image_case("Linear", "REPEAT", scale=1.3)
    c["image_cubic"] = image_case("Cubic", "EXTEND", scale=1.3)
    # Clip: linear and cubic fade out over the texels past the edge, alpha with colour.
    c["image_linear_clip"] = image_case("Linear", "CLIP", scale=1.3, alpha_out=True, with_alpha=False)
    c["image_cubic_clip"] = image_case("Cubic", "CLIP", scale=1.3)
    c["image_cubic_repeat_bytes"] = image_case("Cubic", "REPEAT", scale=1.3, is_float=False)
    c["image_srgb_bytes"] = image_case("Closest", "REPEAT", colorspace="sRGB", is_float=False)
    c["image_alpha"] = image_case("Closest", "REPEAT", alpha_out=True, is_float=False)
    # Alpha output unused: Cycles' colour is then associated (premultiplied) for straight images.
    c["image_straight_colour"] = image_case("Closest", "REPEAT", colorspace="sRGB", is_float=False,
                                            with_alpha=True)
    # Premultiplied image with the Alpha output used: the colour is unassociated.
    c["image_premul_alpha"] = image_case("Closest", "REPEAT", alpha_out=True, alpha_mode="PREMUL")
    c["texcoords"] = texcoord_case
    c["normal_map_tangent"] = normal_map_case("TANGENT")
    c["normal_map_object"] = normal_map_case("OBJECT")
    c.update(procedural_cases())
    c.update(adjust_cases())
    return c


# -- whole scenes -------------------------------------------------------------------

SCENE_SPP = 64
SCENE_RES = 64


def roughness_group():
    """A node group computing roughness from a checker factor: 0.3 + 0.4 * fac."""
    group = bpy.data.node_groups.new("roughness_from_fac", "ShaderNodeTree")
    group.inputs.new("NodeSocketFloat", "fac")
    group.outputs.new("NodeSocketFloat", "roughness")
    gi, go = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    m = group.nodes.new("ShaderNodeMath")
    m.operation = "MULTIPLY_ADD"
    m.inputs[1].default_value, m.inputs[2].default_value = 0.4, 0.3
    group.links.new(gi.outputs[0], m.inputs[0])
    group.links.new(m.outputs[0], go.inputs[0])
    return group


def textured_scene():
    """A lit cube on a ground plane, both textured through UVs, a Mapping node and a node group."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=6.0)
    ground = bpy.context.active_object
    bpy.ops.mesh.primitive_cube_add(size=1.2, location=(0.0, 0.0, 0.6), rotation=(0.0, 0.0, 0.5))
    cube = bpy.context.active_object
    material = bpy.data.materials.new("textured")
    material.use_nodes = True
    nt = material.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    tex = node(nt, "ShaderNodeTexImage", interpolation="Linear", extension="REPEAT")
    tex.image = make_image("albedo", 16, 16, is_float=False, colorspace="sRGB")
    coord = node(nt, "ShaderNodeTexCoord")
    mapping = node(nt, "ShaderNodeMapping", vector_type="POINT")
    mapping.inputs["Scale"].default_value = (2.0, 3.0, 1.0)
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, 0.4)
    nt.links.new(coord.outputs["UV"], mapping.inputs[0])
    nt.links.new(mapping.outputs[0], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    checker = node(nt, "ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 4.0
    group = node(nt, "ShaderNodeGroup")
    group.node_tree = roughness_group()
    nt.links.new(checker.outputs["Fac"], group.inputs[0])
    nt.links.new(group.outputs[0], bsdf.inputs["Roughness"])
    for ob in (ground, cube):
        ob.data.materials.append(material)
    add_sun_camera_and_grey_world(scene, (4.0, -4.0, 3.5), (0.05, 0.05, 0.05))
    r = scene.render
    r.resolution_x = r.resolution_y = SCENE_RES
    r.resolution_percentage = 100
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    configure_cycles_reference(scene, SCENE_SPP)
    scene.coherent.samples = SCENE_SPP
    return scene


def bump_normals(size, waves=2.0, amplitude=1.5):
    """A float Non-Color tangent-space normal map of smooth bumps."""
    image = bpy.data.images.new("bump_normals", size, size, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    y, x = np.mgrid[0:size, 0:size].astype(np.float32) * (2.0 * np.pi * waves / size)
    n = np.stack([amplitude * np.cos(x) * np.sin(y), amplitude * np.sin(x) * np.cos(y), np.ones_like(x)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    image.pixels.foreach_set(np.concatenate([0.5 * n + 0.5, np.ones((size, size, 1), np.float32)], -1).ravel())
    return image


def normal_mapped_scene():
    """A smooth UV sphere with a tangent-space normal map of bumps, on a plain ground plane, sun-lit."""
    scene = textured_scene()  # camera, sun, world, film and sample settings of the textured scene
    for ob in list(scene.objects):
        if ob.type == "MESH":
            bpy.data.objects.remove(ob, do_unlink=True)
    bpy.ops.mesh.primitive_plane_add(size=6.0)
    ground = bpy.context.active_object
    ground_mat = bpy.data.materials.new("ground")
    ground_mat.use_nodes = True
    ground_mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.5, 0.45, 0.4, 1.0)
    ground.data.materials.append(ground_mat)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=1.4, location=(0.0, 0.0, 1.4))
    bpy.ops.object.shade_smooth()
    sphere = bpy.context.active_object
    material = bpy.data.materials.new("normal_mapped")
    material.use_nodes = True
    nt = material.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.7, 0.3, 0.2, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.4
    tex = node(nt, "ShaderNodeTexImage", interpolation="Linear", extension="REPEAT")
    tex.name, tex.image = "normal_tex", bump_normals(256)
    nmap = node(nt, "ShaderNodeNormalMap", space="TANGENT")
    nt.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    sphere.data.materials.append(material)
    return scene


def malformed_scene():
    """A missing image file and node groups nested deeper than the compiler's limit."""
    scene, plane, material = setup_scene()
    nt, emission = fresh_tree(material)
    tex = node(nt, "ShaderNodeTexImage")
    tex.name = "missing_tex"
    missing = bpy.data.images.new("missing", 4, 4)
    missing.source = "FILE"
    missing.filepath = "/nonexistent/missing_texture.png"
    tex.image = missing
    nt.links.new(tex.outputs["Color"], emission.inputs["Color"])
    inner = None
    for depth in range(20):
        group = bpy.data.node_groups.new(f"level{depth}", "ShaderNodeTree")
        group.inputs.new("NodeSocketFloat", "x")
        group.outputs.new("NodeSocketFloat", "y")
        gi, go = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
        if inner is None:
            group.links.new(gi.outputs[0], go.inputs[0])
        else:
            g = group.nodes.new("ShaderNodeGroup")
            g.node_tree = inner
            group.links.new(gi.outputs[0], g.inputs[0])
            group.links.new(g.outputs[0], go.inputs[0])
        inner = group
    top = node(nt, "ShaderNodeGroup")
    top.name = "deep_group"
    top.node_tree = inner
    u, _, _ = separate(nt, pixel_uv(nt))
    nt.links.new(u, top.inputs[0])
    # Strength = 1 + what the too-deep group gives (its default, 0): the magenta stays visible.
    add = node(nt, "ShaderNodeMath", operation="ADD")
    add.inputs[1].default_value = 1.0
    nt.links.new(top.outputs[0], add.inputs[0])
    nt.links.new(add.outputs[0], emission.inputs["Strength"])
    return scene


PASSES = ("normal", "diffuse_direct", "diffuse_indirect", "diffuse_color", "glossy_direct", "glossy_color", "emit")


def _quad(name, x, material):
    bpy.ops.mesh.primitive_plane_add(size=0.45, location=(x, 0.0, 0.0))
    ob = bpy.context.active_object
    ob.name = name
    ob.data.materials.append(material)


def _nan_image():
    """A float image held only inside Blender, every other pixel NaN (some channels +inf)."""
    image = bpy.data.images.new("nan_pixels", 8, 8, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    pixels = np.full((8, 8, 4), 0.5, np.float32)
    pixels[::2, :, :3] = np.nan
    pixels[1::4, ::2, 0] = np.inf  # 4 rows x 8 x 3 NaN + 2 rows x 4 inf = 104 bad values
    image.pixels.foreach_set(pixels.ravel())
    return image


def malformed_data_scene(out_dir):
    """Bad data rather than bad structure, each on its own quad with its own material:
    a zero-byte image file, an image with NaN and infinite pixels (as emission and as
    a Principled base colour and normal map), and a cycle of links between two nodes.
    Rendered to a multilayer EXR with light passes, all of which must stay finite."""
    scene, plane, material = setup_scene()
    bpy.data.objects.remove(plane, do_unlink=True)
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sun.rotation_euler = (0.3, 0.2, 0.0)
    scene.collection.objects.link(sun)
    empty_path = os.path.join(out_dir, "zero_size.png")
    open(empty_path, "wb").close()
    empty = bpy.data.images.load(empty_path)
    empty.name = "zero_size"
    nan_image = _nan_image()
    for k, (name, image) in enumerate((("zero_size_image", empty), ("nan_emission", nan_image))):
        mat = bpy.data.materials.new(name)
        mat.use_nodes = True
        nt, emission = fresh_tree(mat)
        tex = node(nt, "ShaderNodeTexImage", interpolation="Closest")
        tex.name, tex.image = f"{name}_tex", image
        nt.links.new(tex.outputs["Color"], emission.inputs["Color"])
        _quad(name, -0.75 + 0.5 * k, mat)
    mat = bpy.data.materials.new("nan_principled")
    mat.use_nodes = True
    nt = mat.node_tree
    tex = node(nt, "ShaderNodeTexImage", interpolation="Linear")
    tex.name, tex.image = "nan_principled_tex", nan_image
    nmap = node(nt, "ShaderNodeNormalMap")
    nt.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    bsdf = nt.nodes["Principled BSDF"]
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    nt.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    _quad("nan_principled", 0.25, mat)
    mat = bpy.data.materials.new("cyclic_links")
    mat.use_nodes = True
    nt, emission = fresh_tree(mat)
    loop_a, loop_b = node(nt, "ShaderNodeMath", operation="ADD"), node(nt, "ShaderNodeMath", operation="ADD")
    loop_a.name, loop_b.name = "loop_a", "loop_b"
    nt.links.new(loop_a.outputs[0], loop_b.inputs[0])
    nt.links.new(loop_b.outputs[0], loop_a.inputs[0])  # Blender keeps it, marked invalid
    nt.links.new(loop_b.outputs[0], emission.inputs["Strength"])
    _quad("cyclic_links", 0.75, mat)
    scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    for name in PASSES:
        setattr(scene.view_layers[0], f"use_pass_{name}", True)
    scene.coherent.samples = 4
    return scene


def render_both(scene, out_dir, name, engines=("CYCLES", "COHERENT")):
    for engine in engines:
        scene.render.engine = engine
        scene.render.filepath = os.path.join(out_dir, f"{name}_{engine.lower()}.exr")
        bpy.ops.render.render(write_still=True)
    print(f"NODE_CASE {name}")
    sys.stdout.flush()


def main():
    args = sys.argv[sys.argv.index("--") + 1:]
    out_dir, names = args[0], args[1:]
    if names == ["scene_textured"]:
        render_both(textured_scene(), out_dir, "scene_textured")
        return
    if names == ["scene_normal_mapped"]:
        render_both(normal_mapped_scene(), out_dir, "scene_normal_mapped")
        return
    if names == ["malformed"]:
        render_both(malformed_scene(), out_dir, "malformed", engines=("COHERENT",))
        return
    if names == ["malformed_data"]:
        render_both(malformed_data_scene(out_dir), out_dir, "malformed_data", engines=("COHERENT",))
        return
    scene, plane, material = setup_scene()
    all_cases = cases()
    for name in names or list(all_cases):
        nt, emission = fresh_tree(material)
        driver = all_cases[name](nt)
        restore = None
        if isinstance(driver, tuple) and driver[0] == "custom":  # (custom, material builder, scene setup)
            nt.links.new(driver[1](nt), emission.inputs["Color"])
            restore = driver[2](scene, plane)
        elif isinstance(driver, tuple) and driver[0] == "lit":  # (lit, builder of its own lit material)
            driver[1](scene, material)
        elif isinstance(driver, tuple):  # a lit case that builds its own material
            build_normal_map(scene, material, driver[1])
        else:
            nt.links.new(driver, emission.inputs["Color"])
        render_both(scene, out_dir, name)
        if restore is not None:
            restore()


if __name__ == "__main__":
    main()
