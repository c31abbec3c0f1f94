# Run by test_robustness.py after loading blend_scenes/cornell_box.blend:
#
#   blender -b cornell_box.blend --python broken_scene.py -E COHERENT ... -f 1
#
# Adds content the engine must survive: a mesh with a NaN vertex and zero-area
# faces, a material using a shader node the engine does not support (Toon
# BSDF), and one whose Base Color is driven by a texture. The original scene
# stays intact, so the image must still show the Cornell box.

import bpy

scene = bpy.context.scene
nan = float("nan")

# A small mesh on the floor: one good triangle, one with a NaN vertex, one
# with all three vertices equal, one with three collinear vertices.
verts = [
    (0.6, -0.9, 0.01), (0.9, -0.9, 0.01), (0.75, -0.6, 0.01),  # good
    (0.1, -0.9, 0.01), (nan, -0.9, 0.01), (0.2, -0.6, 0.01),   # NaN
    (0.3, -0.3, 0.5), (0.3, -0.3, 0.5), (0.3, -0.3, 0.5),      # a point
    (-0.5, -0.5, 0.3), (-0.4, -0.5, 0.3), (-0.3, -0.5, 0.3),   # a line
]
faces = [(0, 1, 2), (3, 4, 5), (6, 7, 8), (9, 10, 11)]
mesh = bpy.data.meshes.new("BrokenMesh")
mesh.from_pydata(verts, [], faces)  # no validate(): keep the bad data
mesh.update()
assert any(v.co.x != v.co.x for v in mesh.vertices), "the NaN vertex must survive into the mesh"

toon = bpy.data.materials.new("ToonMaterial")
toon.use_nodes = True
nodes = toon.node_tree.nodes
nodes.clear()
out = nodes.new("ShaderNodeOutputMaterial")
toon_node = nodes.new("ShaderNodeBsdfToon")
toon.node_tree.links.new(toon_node.outputs["BSDF"], out.inputs["Surface"])
mesh.materials.append(toon)

broken = bpy.data.objects.new("BrokenObject", mesh)
scene.collection.objects.link(broken)

# A textured cube inside the box.
tex_mesh = bpy.data.meshes.new("TexturedCube")
s = 0.15
tex_mesh.from_pydata(
    [(x * s + 0.4, y * s - 0.4, z * s + 0.75) for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], [],
    [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)])
tex_mesh.update()
textured = bpy.data.materials.new("TexturedMaterial")
textured.use_nodes = True
bsdf = textured.node_tree.nodes["Principled BSDF"]
texture = textured.node_tree.nodes.new("ShaderNodeTexPointDensity")  # a texture COHERENT does not support
textured.node_tree.links.new(texture.outputs["Color"], bsdf.inputs["Base Color"])
tex_mesh.materials.append(textured)
scene.collection.objects.link(bpy.data.objects.new("TexturedObject", tex_mesh))

print("broken_scene: added BrokenObject (NaN vertex, degenerate faces, Toon BSDF) and TexturedObject")
