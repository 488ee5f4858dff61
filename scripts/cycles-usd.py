"""Render a USD groom on its head with Blender's Cycles, from the same points cuticle reads.

Debian 12's Blender 3.4 is built without USD, so the stage is read here with Pixar's own library (`pip install
usd-core`; its site-packages are added to Blender's path) and rebuilt in Blender:

    blender -b --factory-startup --python scripts/cycles-usd.py -- STAGE.usdc --out cycles.exr \
        [--res 400] [--spp 64] [--threads 2] [--pxr SITE_PACKAGES]

- Meshes: points in world space (each prim's local-to-world transform), faces as authored (Blender keeps
  polygons; Cycles triangulates them), shaded smooth unless `subdivisionScheme = "none"`, as cuticle does (neither
  subdivides).
- Curves: `bspline` curves with `pinned` or `nonperiodic` wrap and vertex or constant widths (what
  `scripts/usd-test-data.py --head` writes). cuticle traces the uniform cubic B-spline; Cycles 3.4 draws
  Catmull-Rom curves through the points it is given, so each B-spline segment is evaluated at 8 points (and its
  radius with it) and Cycles gets those: the two curves then differ by far less than a strand's width.
- Camera: the first Camera prim's world transform, vertical field of view from focalLength and
  verticalAperture. Lights: DistantLight as a sun (strength = intensity), a DomeLight's colour x intensity as the
  world colour. USD is y-up here and so is the scene built: Blender's z-up only changes the viewport.
- Film: transparent (alpha = coverage), Cycles' Gaussian filter of width 3, as cuticle's (σ = 0.5 px): measured
  on this stage at 400², 64 spp, the mean per-pixel alpha difference is 0.0024 with width 3 and 0.0060 with
  width 6. Hair: Principled Hair with Cycles' defaults (only the coverage is compared).
"""
import argparse
import math
import sys
import time

import bpy
from mathutils import Matrix


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="cycles-usd.py")
    ap.add_argument("stage")
    ap.add_argument("--out", required=True, help="linear EXR")
    ap.add_argument("--res", type=int, default=400)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--samples-per-segment", type=int, default=8)
    ap.add_argument("--pxr", default="/root/.pyenv/versions/3.11.7/lib/python3.11/site-packages",
                    help="site-packages holding usd-core's pxr")
    return ap.parse_args(argv)


def world_matrix(prim, Usd, UsdGeom):
    m = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode.Default())
    # Gf matrices are row-major with row vectors; Blender's are column vectors.
    return Matrix([[m[c][r] for c in range(4)] for r in range(4)])


def bspline(p0, p1, p2, p3, u):
    t = 1.0 - u
    w = (t * t * t / 6.0, (3 * u ** 3 - 6 * u * u + 4) / 6.0, (-3 * u ** 3 + 3 * u * u + 3 * u + 1) / 6.0, u ** 3 / 6.0)
    return [w[0] * a + w[1] * b + w[2] * c + w[3] * d for a, b, c, d in zip(p0, p1, p2, p3)]


def curve_points(prim, Usd, UsdGeom, per_segment):
    """Each strand's B-spline evaluated at `per_segment` points per segment: lists of (x, y, z, radius)."""
    curves = UsdGeom.BasisCurves(prim)
    if curves.GetBasisAttr().Get() != "bspline" or curves.GetTypeAttr().Get() != "cubic":
        sys.exit(f"{prim.GetPath()}: only cubic bspline curves are rebuilt here")
    wrap = curves.GetWrapAttr().Get()
    m = world_matrix(prim, Usd, UsdGeom)
    pts = [m @ __import__("mathutils").Vector(p) for p in curves.GetPointsAttr().Get()]
    counts = list(curves.GetCurveVertexCountsAttr().Get())
    widths = list(curves.GetWidthsAttr().Get() or [0.01])
    vertex = curves.GetWidthsInterpolation() == "vertex"
    scale = abs(m.to_3x3().determinant()) ** (1.0 / 3.0)
    strands, at = [], 0
    for n in counts:
        cps = [[pts[at + i].x, pts[at + i].y, pts[at + i].z,
                0.5 * scale * (widths[at + i] if vertex else widths[0])] for i in range(n)]
        at += n
        if wrap == "pinned":
            cps = [[2 * a - b for a, b in zip(cps[0], cps[1])]] + cps + [[2 * a - b for a, b in zip(cps[-1], cps[-2])]]
            for r in (cps[0], cps[-1]):
                r[3] = max(r[3], 0.0)
        out = []
        for k in range(len(cps) - 3):
            for j in range(per_segment):
                out.append(bspline(*cps[k:k + 4], j / per_segment))
        out.append(bspline(*cps[-4:], 1.0))
        strands.append(out)
    return strands


def build_hair(strands):
    me = bpy.data.meshes.new("hair_src")
    flat = [p for s in strands for p in s]
    me.vertices.add(len(flat))
    me.vertices.foreach_set("co", [c for p in flat for c in p[:3]])
    edges, o = [], 0
    for s in strands:
        for i in range(o, o + len(s) - 1):
            edges += [i, i + 1]
        o += len(s)
    me.edges.add(len(edges) // 2)
    me.edges.foreach_set("vertices", edges)
    me.attributes.new("radius", "FLOAT", "POINT").data.foreach_set("value", [p[3] for p in flat])
    ob = bpy.data.objects.new("hair", me)
    bpy.context.scene.collection.objects.link(ob)
    ng = bpy.data.node_groups.new("mesh_to_curve", "GeometryNodeTree")
    ng.inputs.new("NodeSocketGeometry", "Geometry")
    ng.outputs.new("NodeSocketGeometry", "Geometry")
    gi, go = ng.nodes.new("NodeGroupInput"), ng.nodes.new("NodeGroupOutput")
    m2c = ng.nodes.new("GeometryNodeMeshToCurve")
    ng.links.new(gi.outputs[0], m2c.inputs["Mesh"])
    ng.links.new(m2c.outputs[0], go.inputs[0])
    ob.modifiers.new("m2c", "NODES").node_group = ng
    bpy.context.view_layer.update()
    for o2 in bpy.context.scene.objects:
        o2.select_set(False)
    ob.select_set(True)
    bpy.context.view_layer.objects.active = ob
    bpy.ops.object.convert(target="CURVES")
    hair = bpy.context.view_layer.objects.active
    mat = bpy.data.materials.new("hair")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfHairPrincipled")
    out = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    hair.data.materials.append(mat)
    return hair


def build_mesh(prim, Usd, UsdGeom):
    mesh = UsdGeom.Mesh(prim)
    m = world_matrix(prim, Usd, UsdGeom)
    pts = [m @ __import__("mathutils").Vector(p) for p in mesh.GetPointsAttr().Get()]
    counts = list(mesh.GetFaceVertexCountsAttr().Get())
    idx = list(mesh.GetFaceVertexIndicesAttr().Get())
    faces, at = [], 0
    for c in counts:
        faces.append(idx[at:at + c])
        at += c
    me = bpy.data.meshes.new(str(prim.GetName()))
    me.from_pydata([tuple(p) for p in pts], [], faces)
    smooth = mesh.GetSubdivisionSchemeAttr().Get() != "none"
    me.polygons.foreach_set("use_smooth", [smooth] * len(me.polygons))
    ob = bpy.data.objects.new(str(prim.GetName()), me)
    bpy.context.scene.collection.objects.link(ob)
    color = (0.5, 0.5, 0.5)
    dc = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
    if dc and dc.Get():
        color = tuple(dc.Get()[0])
    mat = bpy.data.materials.new(str(prim.GetName()))
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*color, 1.0)
    out = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    me.materials.append(mat)


def main():
    args = parse_args()
    sys.path.append(args.pxr)
    from pxr import Usd, UsdGeom, UsdLux

    start = time.perf_counter()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    stage = Usd.Stage.Open(args.stage)
    camera_done = False
    world = bpy.data.worlds.new("world")
    scene.world = world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh):
            build_mesh(prim, Usd, UsdGeom)
        elif prim.IsA(UsdGeom.BasisCurves):
            build_hair(curve_points(prim, Usd, UsdGeom, args.samples_per_segment))
        elif prim.IsA(UsdGeom.Camera) and not camera_done:
            cam = UsdGeom.Camera(prim)
            data = bpy.data.cameras.new("camera")
            data.sensor_fit = "VERTICAL"
            focal = cam.GetFocalLengthAttr().Get()
            aperture = cam.GetVerticalApertureAttr().Get()
            data.angle = 2.0 * math.atan(0.5 * aperture / focal)
            ob = bpy.data.objects.new("camera", data)
            ob.matrix_world = world_matrix(prim, Usd, UsdGeom)
            scene.collection.objects.link(ob)
            scene.camera = ob
            camera_done = True
        elif prim.IsA(UsdLux.DistantLight):
            light = UsdLux.DistantLight(prim)
            data = bpy.data.lights.new("sun", "SUN")
            data.energy = light.GetIntensityAttr().Get()
            data.angle = 0.0
            ob = bpy.data.objects.new("sun", data)
            ob.matrix_world = world_matrix(prim, Usd, UsdGeom)
            scene.collection.objects.link(ob)
        elif prim.IsA(UsdLux.DomeLight):
            light = UsdLux.DomeLight(prim)
            c = light.GetColorAttr().Get() or (1, 1, 1)
            k = light.GetIntensityAttr().Get()
            world.node_tree.nodes["Background"].inputs["Color"].default_value = (c[0] * k, c[1] * k, c[2] * k, 1)
    if not camera_done:
        sys.exit(f"{args.stage}: no Camera prim")
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = args.spp
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.pixel_filter_type = "GAUSSIAN"
    scene.cycles.filter_width = 3.0
    scene.cycles.max_bounces = 1
    scene.render.film_transparent = True
    scene.render.threads_mode = "FIXED"
    scene.render.threads = args.threads
    scene.render.resolution_x = scene.render.resolution_y = args.res
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.filepath = args.out
    print(f"CYCLES_BUILD_SECONDS {time.perf_counter() - start:.3f}")
    start = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    print(f"CYCLES_RENDER_SECONDS {time.perf_counter() - start:.3f}")


main()
