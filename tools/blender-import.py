# What Blender makes of a bundle (issue 20): imports an object.glb with Blender's own glTF importer
# and prints, as one JSON line after "blender-import: ", each object and, for a mesh, its vertices,
# faces, connected parts (vertices joined by edges) and boundary edges.
#
#   blender -b --factory-startup --python-exit-code 2 --python tools/blender-import.py -- BUNDLE.glb
#       [--expect REPORT.json]
#
# With --expect (the bundle's report.json), also checks what issue 20 asks of the import and exits 1
# naming the first check that fails:
#   - one mesh object, with the capture mesh's triangles as faces (capture.mesh_triangles);
#   - as many vertices as the atlas wrote (report.json atlas.vertices.atlas), at most 1.3 times the
#     input mesh's (atlas.vertices.mesh);
#   - at most one connected part per atlas chart (atlas.charts), not one per triangle.
import json
import sys

import bmesh
import bpy
import numpy

# Debian 12's Blender 3.4 importer still uses numpy.bool, which its numpy (1.24) removed.
if not hasattr(numpy, "bool"):
    numpy.bool = bool


def parts(bm):
    """Connected parts of a mesh: vertices joined through edges."""
    seen = [False] * len(bm.verts)
    count = 0
    bm.verts.ensure_lookup_table()
    for start in bm.verts:
        if seen[start.index]:
            continue
        count += 1
        seen[start.index] = True
        stack = [start]
        while stack:
            v = stack.pop()
            for e in v.link_edges:
                w = e.other_vert(v)
                if not seen[w.index]:
                    seen[w.index] = True
                    stack.append(w)
    return count


def main(argv):
    if not argv or argv[0].startswith("-"):
        print("usage: blender -b --python tools/blender-import.py -- BUNDLE.glb [--expect REPORT.json]")
        return 2
    path = argv[0]
    expect = argv[argv.index("--expect") + 1] if "--expect" in argv else None
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)
    objects = []
    for ob in bpy.context.scene.objects:
        entry = {"name": ob.name, "type": ob.type}
        if ob.type == "MESH":
            bm = bmesh.new()
            bm.from_mesh(ob.data)
            entry.update(vertices=len(bm.verts), faces=len(bm.faces), parts=parts(bm),
                         boundary_edges=sum(1 for e in bm.edges if e.is_boundary),
                         materials=[m.name for m in ob.data.materials if m is not None])
            bm.free()
        objects.append(entry)
    print("blender-import: " + json.dumps({"bundle": path, "blender": bpy.app.version_string, "objects": objects}))
    if expect is None:
        return 0
    with open(expect, encoding="utf-8") as f:
        report = json.load(f)
    atlas, triangles = report["atlas"], report["capture"]["mesh_triangles"]
    meshes = [o for o in objects if o["type"] == "MESH"]
    failures = []
    if len(meshes) != 1:
        failures.append(f"{len(meshes)} mesh objects, 1 expected")
    else:
        m = meshes[0]
        written, mesh = atlas["vertices"]["atlas"], atlas["vertices"]["mesh"]
        if m["faces"] != triangles:
            failures.append(f"{m['faces']} faces, the mesh has {triangles} triangles")
        if m["vertices"] != written:
            failures.append(f"{m['vertices']} vertices, the atlas wrote {written}")
        if m["vertices"] > 1.3 * mesh:
            failures.append(f"{m['vertices']} vertices, more than 1.3 times the input mesh's {mesh}")
        if m["parts"] > atlas["charts"]:
            failures.append(f"{m['parts']} connected parts, more than the atlas's {atlas['charts']} charts")
    for f in failures:
        print("blender-import: FAIL: " + f)
    return 1 if failures else 0


sys.exit(main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []))
