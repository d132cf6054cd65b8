# Imports a glTF file in Blender (headless) and writes what an artist would see as JSON:
# objects by type, meshes, materials, colour attributes, triangles, armatures and their bones,
# actions and their frame ranges, lights, cameras, and for skinned meshes the evaluated (posed)
# mesh at three frames of each action: the largest distance between vertices that share a
# rest position (a crack under Blender's own skinning is a non-zero distance).
#
#   blender -b --factory-startup --python-exit-code 1 --python inspect_gltf.py -- IN.glb OUT.json
#
# The import error, if any, is written as {"error": "..."} (Blender 3.4 refuses a file that
# requires an extension it lacks, e.g. EXT_mesh_gpu_instancing).
import json
import sys

# Debian's Blender 3.4 glTF importer uses numpy.bool, which numpy 1.24 removed (a Blender bug).
import numpy

if not hasattr(numpy, "bool"):
    numpy.bool = bool

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
source, target = args[0], args[1]

bpy.ops.wm.read_factory_settings(use_empty=True)
out = {}
try:
    result = bpy.ops.import_scene.gltf(filepath=source)
    if "FINISHED" not in result:
        out["error"] = "import returned " + ",".join(sorted(result))
except Exception as e:  # the importer reports a refused file as an exception
    out["error"] = str(e)

if "error" not in out:
    objects = list(bpy.context.scene.objects)
    out["objects"] = {}
    for o in objects:
        out["objects"][o.type] = out["objects"].get(o.type, 0) + 1
    meshes = {o.data.name: o.data for o in objects if o.type == "MESH"}
    out["meshes"] = len(meshes)
    for m in meshes.values():
        m.calc_loop_triangles()
    out["mesh_triangles"] = sum(len(m.loop_triangles) for m in meshes.values())
    out["object_triangles"] = sum(
        len(o.data.loop_triangles) for o in objects if o.type == "MESH"
    )
    out["vertices"] = sum(len(m.vertices) for m in meshes.values())
    out["materials"] = len({s.material.name for o in objects if o.type == "MESH"
                             for s in o.material_slots if s.material})
    out["color_attributes"] = sum(
        1 for m in meshes.values() for a in getattr(m, "color_attributes", []))
    out["linked_duplicates"] = sum(1 for o in objects if o.type == "MESH") - len(meshes)
    out["bones"] = [len(o.data.bones) for o in objects if o.type == "ARMATURE"]
    out["actions"] = {a.name: [a.frame_range[0], a.frame_range[1]] for a in bpy.data.actions}
    out["lights"] = sum(1 for o in objects if o.type == "LIGHT")
    out["cameras"] = sum(1 for o in objects if o.type == "CAMERA")

    # Cracks under Blender's skinning: vertices at one rest position must stay together.
    skinned = [o for o in objects if o.type == "MESH" and any(
        m.type == "ARMATURE" for m in o.modifiers)]
    gaps = []
    for o in skinned:
        groups = {}
        for v in o.data.vertices:
            key = tuple(round(c, 5) for c in v.co)
            groups.setdefault(key, []).append(v.index)
        shared = [g for g in groups.values() if len(g) > 1]
        armature = next(m.object for m in o.modifiers if m.type == "ARMATURE")
        actions = list(bpy.data.actions)
        for action in actions or [None]:
            if action is not None and armature.animation_data is not None:
                armature.animation_data.action = action
            start, end = (action.frame_range if action is not None else (1, 1))
            for frame in (start, (start + end) / 2, end):
                bpy.context.scene.frame_set(int(round(frame)))
                depsgraph = bpy.context.evaluated_depsgraph_get()
                evaluated = o.evaluated_get(depsgraph).to_mesh()
                worst = 0.0
                for g in shared:
                    first = evaluated.vertices[g[0]].co
                    for i in g[1:]:
                        worst = max(worst, (evaluated.vertices[i].co - first).length)
                o.evaluated_get(depsgraph).to_mesh_clear()
                gaps.append({"object": o.name, "action": action.name if action else None,
                             "frame": frame, "shared": len(shared), "max_gap": worst})
    out["skin_gaps"] = gaps

with open(target, "w") as f:
    json.dump(out, f, indent=1)
