"""Run inside Blender: import a glTF file and print what Blender built as one JSON line.

Usage: blender -b --factory-startup --python-exit-code 1 --python blender_gltf_check.py --
FILE.glb FPS FRAME

The scene's frame rate is set to ``FPS`` before the import, so the importer keys one Blender
frame per frame of the clip; ``FRAME`` counts from the action's first frame.
"""

import json
import sys

import bpy
import numpy

# Blender 3.4's glTF importer uses np.bool, which NumPy 1.24-1.26 do not have (2.x has it again).
if not hasattr(numpy, "bool"):
    numpy.bool = numpy.bool_
args = sys.argv[sys.argv.index("--") + 1:]
path, fps, frame = args[0], float(args[1]), int(args[2])
scene = bpy.context.scene
for obj in list(scene.objects):
    bpy.data.objects.remove(obj)
scene.render.fps, scene.render.fps_base = round(fps), round(fps) / fps
bpy.ops.import_scene.gltf(filepath=path)
arm = next(o for o in scene.objects if o.type == "ARMATURE")
meshes = [o for o in scene.objects if o.type == "MESH"]
bones = arm.data.bones
action = arm.animation_data.action
start, end = action.frame_range
scene.frame_set(round(start) + frame)
# Blender is Z-up: a glTF point (x, y, z) lands at (x, -z, y); map it back to glTF's axes.
heads = [list(arm.matrix_world @ arm.pose.bones[b.name].head) for b in bones]
heads = [[h[0], h[2], -h[1]] for h in heads]
skinned = [m for m in meshes if any(md.type == "ARMATURE" and md.object == arm
                                    for md in m.modifiers)]
depsgraph = bpy.context.evaluated_depsgraph_get()
corners = []
for m in skinned:
    evaluated = m.evaluated_get(depsgraph)
    corners += [list(evaluated.matrix_world @ v.co) for v in evaluated.data.vertices]
low = [min(c[i] for c in corners) for i in range(3)] if corners else []
high = [max(c[i] for c in corners) for i in range(3)] if corners else []
print("EMOTIVE_CHECK " + json.dumps({
    "bones": [b.name for b in bones],
    "parents": [b.parent.name if b.parent else None for b in bones],
    "frame_start": start,
    "frame_end": end,
    "heads": heads,
    "skinned_meshes": len(skinned),
    "vertex_groups": sorted({g.name for m in skinned for g in m.vertex_groups}),
    "mesh_min": [low[0], low[2], -high[1]] if corners else None,
    "mesh_max": [high[0], high[2], -low[1]] if corners else None,
}))
