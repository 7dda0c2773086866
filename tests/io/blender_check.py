"""Run inside Blender: import a BVH file and print what Blender built as one JSON line.

Usage: blender -b --factory-startup --python-exit-code 1 --python blender_check.py -- FILE.bvh FRAME
"""

import builtins
import json
import sys

import bpy

_open = builtins.open


def _open_without_u(file, mode="r", *args, **kwargs):
    # Blender 3.4's importer opens files with mode "rU", which Python 3.11 removed.
    return _open(file, mode.replace("U", ""), *args, **kwargs)


builtins.open = _open_without_u
path = sys.argv[sys.argv.index("--") + 1]
bpy.ops.import_anim.bvh(filepath=path, update_scene_fps=True, update_scene_duration=True)
arm = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
bones = arm.data.bones
action = arm.animation_data.action
start, end = action.frame_range
frame = round(start) + int(sys.argv[sys.argv.index("--") + 2])
bpy.context.scene.frame_set(frame)
# Blender is Z-up: a BVH point (x, y, z) lands at (x, -z, y); map it back to the file's axes.
heads = [list(arm.matrix_world @ arm.pose.bones[b.name].head) for b in bones]
heads = [[h[0], h[2], -h[1]] for h in heads]
print("EMOTIVE_CHECK " + json.dumps({
    "bones": [b.name for b in bones],
    "parents": [b.parent.name if b.parent else None for b in bones],
    "frames": round(end - start) + 1,
    "heads": heads,
    "fps": bpy.context.scene.render.fps / bpy.context.scene.render.fps_base,
}))
