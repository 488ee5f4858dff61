#!/usr/bin/env python3
"""Writes the USD reader's test files with Pixar's own library (`pip install usd-core`, the `pxr` module).

    scripts/usd-test-data.py                 # tests/data/usd/: groom.usda/.usdc/.usdz, bases.usda,
                                             # instancing.usda and .expected, textured.usda/.usdz
                                             # and checker.png
    scripts/usd-test-data.py --big DIR       # DIR/big.usdc and DIR/big.hair: 100 000 strands, for timing
    scripts/usd-test-data.py --head DIR      # DIR/head-groom.usdc: 5 000 strands on a head, camera and sun, for
                                             # comparing with Cycles (scripts/cycles-usd.py)

Deterministic: every value comes from closed forms (no random numbers, no timestamps), so running it again
rewrites the same files.

The groom's dome light names `sky.exr` beside it: a 32x16 vertical gradient written by OpenImageIO,

    oiiotool --pattern fill:top=0.45,0.55,0.75:bottom=0.15,0.12,0.1 32x16 3 -d half --compression zip \
        -o tests/data/usd/sky.exr
"""

import math
import os
import struct
import sys

from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, UsdUtils

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "tests", "data", "usd")


def sphere(stage, path, radius, slices, stacks):
    """A UV sphere: triangle fans at the poles, quads between; per-vertex displayColor."""
    mesh = UsdGeom.Mesh.Define(stage, path)
    pts = [(0.0, radius, 0.0)]
    for j in range(1, stacks):
        theta = math.pi * j / stacks
        for i in range(slices):
            phi = 2.0 * math.pi * i / slices
            pts.append((radius * math.sin(theta) * math.cos(phi), radius * math.cos(theta),
                        radius * math.sin(theta) * math.sin(phi)))
    pts.append((0.0, -radius, 0.0))
    counts, idx = [], []
    ring = lambda j, i: 1 + (j - 1) * slices + (i % slices)
    for i in range(slices):
        counts.append(3)
        idx += [0, ring(1, i + 1), ring(1, i)]
    for j in range(1, stacks - 1):
        for i in range(slices):
            counts.append(4)
            idx += [ring(j, i), ring(j, i + 1), ring(j + 1, i + 1), ring(j + 1, i)]
    last = len(pts) - 1
    for i in range(slices):
        counts.append(3)
        idx += [last, ring(stacks - 1, i), ring(stacks - 1, i + 1)]
    mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    mesh.CreateFaceVertexCountsAttr(counts)
    mesh.CreateFaceVertexIndicesAttr(idx)
    return mesh


def groom_stage(path):
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    head = UsdGeom.Xform.Define(stage, "/World/Head")
    head.AddTranslateOp().Set(Gf.Vec3d(0.0, 1.5, 0.0))
    mesh = sphere(stage, "/World/Head/Skin", 1.0, 16, 12)
    mat = UsdShade.Material.Define(stage, "/World/Looks/Skin")
    shader = UsdShade.Shader.Define(stage, "/World/Looks/Skin/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.8, 0.6, 0.5))
    mat.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)

    # 36 strands on the upper half of the head: pinned B-splines of 6 points, per-vertex widths and colour.
    hair = UsdGeom.Xform.Define(stage, "/World/Head/Hair")
    hair.AddRotateYOp().Set(30.0)
    curves = UsdGeom.BasisCurves.Define(stage, "/World/Head/Hair/Strands")
    curves.CreateTypeAttr("cubic")
    curves.CreateBasisAttr("bspline")
    curves.CreateWrapAttr("pinned")
    pts, counts, widths, colors = [], [], [], []
    for s in range(36):
        theta = 0.15 + 1.1 * (s // 6) / 6.0
        phi = 2.0 * math.pi * (s % 6) / 6.0 + 0.1 * (s // 6)
        n = Gf.Vec3f(math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi))
        counts.append(6)
        for k in range(6):
            t = k / 5.0
            p = n * (1.0 + 0.3 * t) + Gf.Vec3f(0.0, -0.4 * t * t, 0.0)
            pts.append(p)
            widths.append(0.02 * (1.0 - 0.5 * t))
            colors.append(Gf.Vec3f(0.3 + 0.01 * s, 0.2, 0.1))
    curves.CreatePointsAttr(pts)
    curves.CreateCurveVertexCountsAttr(counts)
    curves.CreateWidthsAttr(widths)
    curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    pv = UsdGeom.PrimvarsAPI(curves.GetPrim())
    pv.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex).Set(colors)
    pv.CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.constant).Set([0.75])

    cam = UsdGeom.Camera.Define(stage, "/World/Camera")
    cam.AddTranslateOp().Set(Gf.Vec3d(0.0, 1.5, 8.0))
    cam.CreateFocalLengthAttr(35.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(24.0)
    sun = UsdLux.DistantLight.Define(stage, "/World/Sun")
    sun.AddRotateXOp().Set(-45.0)
    sun.CreateIntensityAttr(3.0)
    sun.CreateAngleAttr(1.0)
    sun.CreateColorAttr(Gf.Vec3f(1.0, 0.9, 0.8))
    dome = UsdLux.DomeLight.Define(stage, "/World/Sky")
    dome.CreateIntensityAttr(0.5)
    dome.CreateExposureAttr(1.0)
    dome.CreateTextureFileAttr(Sdf.AssetPath("sky.exr"))
    UsdLux.SphereLight.Define(stage, "/World/Bulb")
    stage.GetRootLayer().Save()


def bases_stage(path):
    """One prim per basis × wrap × width interpolation, 7 (or 6) points each, small exact values."""
    stage = Usd.Stage.CreateNew(path)
    root = UsdGeom.Xform.Define(stage, "/Bases")
    stage.SetDefaultPrim(root.GetPrim())
    pts7 = [Gf.Vec3f(i, [0, 2, 3, 1, -1, 0.5, 2][i], 1.0 - 0.5 * i) for i in range(7)]
    for ty, basis in [("cubic", "bezier"), ("cubic", "bspline"), ("cubic", "catmullRom"), ("linear", "bspline")]:
        for wrap in ["nonperiodic", "periodic", "pinned"]:
            n = 6 if (basis == "bezier" and ty == "cubic" and wrap == "periodic") else 7
            for interp in ["constant", "uniform", "varying", "vertex", "faceVarying"]:
                name = "%s_%s_%s_%s" % (ty, basis, wrap, interp)
                c = UsdGeom.BasisCurves.Define(stage, "/Bases/" + name)
                c.CreateTypeAttr(ty)
                c.CreateBasisAttr(basis)
                c.CreateWrapAttr(wrap)
                c.CreatePointsAttr(pts7[:n])
                c.CreateCurveVertexCountsAttr([n])
                count = {"constant": 1, "uniform": 1, "vertex": n}.get(interp)
                if count is None and (ty == "linear" or (wrap == "pinned" and basis != "bezier")):
                    # Linear: one per vertex; pinned: one per segment end of n - 1 segments (the schema's and
                    # Hydra's counts; ComputeVaryingDataSize in usd-core 26.11 counts pinned curves as nonperiodic
                    # and a periodic linear curve's ends as n + 1).
                    count = n
                elif count is None:
                    count = c.ComputeVaryingDataSize(Usd.TimeCode.Default())
                c.CreateWidthsAttr([0.25 + 0.125 * k for k in range(count)])
                c.SetWidthsInterpolation(interp)
    stage.GetRootLayer().Save()


def instancing_stage(path):
    """Instanceable prims, a point instancer (rotated, scaled, one instance hidden, a curve and a mesh prototype),
    guide curves and an invisible prim. Beside it, `instancing.expected`: the world points of every strand and mesh
    a final frame shows, as Pixar's library places them (one line each: `curve` or `mesh`, then x y z ...)."""
    stage = Usd.Stage.CreateNew(path)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    world.AddRotateYOp().Set(30.0)
    # A tuft defined once under a class and instanced three times.
    protos = stage.CreateClassPrim("/Protos")
    tuft = UsdGeom.Xform.Define(stage, "/Protos/Tuft")
    c = UsdGeom.BasisCurves.Define(stage, "/Protos/Tuft/Curves")
    c.CreateTypeAttr("cubic")
    c.CreateBasisAttr("bspline")
    c.CreateCurveVertexCountsAttr([4, 4])
    c.CreatePointsAttr([(0, 0, 0), (0, 1, 0), (0.25, 2, 0), (0.5, 3, 0), (1, 0, 0), (1, 1, 0.5), (1, 2, 1), (1, 3, 1.5)])
    c.CreateWidthsAttr([0.1])
    c.SetWidthsInterpolation("constant")
    for i in range(3):
        x = UsdGeom.Xform.Define(stage, "/World/Tuft%d" % i)
        x.AddTranslateOp().Set(Gf.Vec3d(2.0 * i, 0.0, 0.0))
        x.AddScaleOp().Set(Gf.Vec3f(1.0 + 0.5 * i))
        x.GetPrim().GetReferences().AddInternalReference("/Protos/Tuft")
        x.GetPrim().SetInstanceable(True)
    # A point instancer with a curve prototype (its own transform applies inside each instance) and a mesh one.
    pi = UsdGeom.PointInstancer.Define(stage, "/World/Scatter")
    pi.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 5.0))
    p0 = UsdGeom.Xform.Define(stage, "/World/Scatter/Prototypes/Strand")
    p0.AddRotateZOp().Set(15.0)
    cc = UsdGeom.BasisCurves.Define(stage, "/World/Scatter/Prototypes/Strand/C")
    cc.CreateTypeAttr("cubic")
    cc.CreateBasisAttr("bspline")
    cc.CreateCurveVertexCountsAttr([5])
    cc.CreatePointsAttr([(0, 0, 0), (0, 0.5, 0.1), (0.1, 1, 0.2), (0.2, 1.5, 0.2), (0.3, 2, 0.1)])
    cc.CreateWidthsAttr([0.05])
    cc.SetWidthsInterpolation("constant")
    quad = UsdGeom.Mesh.Define(stage, "/World/Scatter/Prototypes/Card")
    quad.CreatePointsAttr([(-0.5, 0, -0.5), (0.5, 0, -0.5), (0.5, 0, 0.5), (-0.5, 0, 0.5)])
    quad.CreateFaceVertexCountsAttr([4])
    quad.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
    quad.CreateDisplayColorAttr([(0.8, 0.6, 0.4)])
    pi.CreatePrototypesRel().SetTargets([p0.GetPath(), quad.GetPath()])
    pi.CreateProtoIndicesAttr([0, 0, 1, 0, 1])
    pi.CreatePositionsAttr([(0, 0, 0), (1, 0, 0), (2, -1, 0), (3, 0, 0), (4, -1, 0)])
    half = math.sqrt(0.5)
    pi.CreateOrientationsAttr([Gf.Quath(1, 0, 0, 0), Gf.Quath(half, 0, half, 0), Gf.Quath(half, half, 0, 0),
                               Gf.Quath(0.5, 0.5, 0.5, 0.5), Gf.Quath(1, 0, 0, 0)])
    pi.CreateScalesAttr([(1, 1, 1), (2, 2, 2), (1, 1, 1), (0.5, 0.5, 0.5), (1.5, 1.5, 1.5)])
    pi.CreateIdsAttr([10, 11, 12, 13, 14])
    pi.CreateInvisibleIdsAttr([13])
    # What a final frame leaves out.
    g = UsdGeom.BasisCurves.Define(stage, "/World/Guides")
    g.CreateCurveVertexCountsAttr([4])
    g.CreatePointsAttr([(9, 0, 0), (9, 1, 0), (9, 2, 0), (9, 3, 0)])
    g.CreatePurposeAttr("guide")
    UsdGeom.Xform.Define(stage, "/World/Hidden")
    h = UsdGeom.BasisCurves.Define(stage, "/World/Hidden/C")
    h.CreateCurveVertexCountsAttr([4])
    h.CreatePointsAttr([(8, 0, 0), (8, 1, 0), (8, 2, 0), (8, 3, 0)])
    UsdGeom.Imageable(stage.GetPrimAtPath("/World/Hidden")).CreateVisibilityAttr("invisible")
    stage.GetRootLayer().Save()

    # The expected world points, from Pixar's library: instance proxies with their world transforms, the
    # instancer's transforms (instancer world × instance × prototype's own ops).
    lines = []
    time = Usd.TimeCode.Default()
    xf = UsdGeom.XformCache(time)
    flat = lambda pts: " ".join("%.9g %.9g %.9g" % (p[0], p[1], p[2]) for p in pts)
    for prim in Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()):
        if not prim.IsA(UsdGeom.BasisCurves) or "Scatter" in str(prim.GetPath()):
            continue
        img = UsdGeom.Imageable(prim)
        if img.ComputeVisibility(time) == "invisible" or img.ComputePurpose() not in ("default", "render"):
            continue
        m = xf.GetLocalToWorldTransform(prim)
        pts = [m.Transform(Gf.Vec3d(*p)) for p in UsdGeom.BasisCurves(prim).GetPointsAttr().Get()]
        counts = UsdGeom.BasisCurves(prim).GetCurveVertexCountsAttr().Get()
        k = 0
        for n in counts:
            lines.append("curve " + flat(pts[k:k + n]))
            k += n
    inst = pi.ComputeInstanceTransformsAtTime(time, time, UsdGeom.PointInstancer.ExcludeProtoXform,
                                              UsdGeom.PointInstancer.IgnoreMask)
    mask = pi.ComputeMaskAtTime(time)
    instancer_world = xf.GetLocalToWorldTransform(pi.GetPrim())
    for i, m in enumerate(inst):
        if mask and not mask[i]:
            continue
        proto = stage.GetPrimAtPath(pi.GetPrototypesRel().GetTargets()[pi.GetProtoIndicesAttr().Get()[i]])
        for prim in Usd.PrimRange(proto):
            if not prim.IsA(UsdGeom.PointBased):
                continue
            # The prim's transform relative to the prototype root, the root's own ops included.
            local = xf.GetLocalToWorldTransform(prim) * xf.GetLocalToWorldTransform(proto.GetParent()).GetInverse()
            full = local * m * instancer_world
            pts = [full.Transform(Gf.Vec3d(*p)) for p in UsdGeom.PointBased(prim).GetPointsAttr().Get()]
            lines.append(("curve " if prim.IsA(UsdGeom.BasisCurves) else "mesh ") + flat(pts))
    with open(os.path.splitext(path)[0] + ".expected", "w") as f:
        f.write("\n".join(lines) + "\n")


def png(path, rows):
    """An 8-bit RGB PNG of `rows` (lists of (r, g, b) bytes), written without any imaging library."""
    import zlib
    h, w = len(rows), len(rows[0])
    raw = b"".join(b"\x00" + bytes(c for px in row for c in px) for row in rows)
    chunk = lambda kind, data: (struct.pack(">I", len(data)) + kind + data
                                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


# The texture's texels, top row first: what tests/usd.rs expects at each texel centre.
TEXELS = [[(255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 255)],
          [(128, 128, 128), (64, 32, 16), (200, 100, 50), (0, 0, 0)]]


def textured_material(stage, path, texture, **inputs):
    """A UsdPreviewSurface whose diffuseColor is a UsdUVTexture of `texture` read at primvar `st`."""
    mat = UsdShade.Material.Define(stage, path)
    surface = UsdShade.Shader.Define(stage, path + "/Surface")
    surface.CreateIdAttr("UsdPreviewSurface")
    tex = UsdShade.Shader.Define(stage, path + "/Texture")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(texture))
    for name, (kind, value) in inputs.items():
        tex.CreateInput(name, kind).Set(value)
    reader = UsdShade.Shader.Define(stage, path + "/St")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.Token).Set("st")
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
    surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(tex.ConnectableAPI(), "rgb")
    mat.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    return mat


def textured_stage(path):
    """Two unit-high cards facing +z under a camera: `Card` (x 0..2) reads checker.png as sRGB (`auto`, an 8-bit
    PNG) with indexed faceVarying st; `Raw` (x 3..5) reads it raw, scaled by 0.5 and biased by 0.1 in red, wrapS
    clamp, with vertex st running past [0, 1] in s. checker.png (4 x 2 texels, TEXELS) is written beside it, and
    the stage is packaged with it as textured.usdz."""
    directory = os.path.dirname(path)
    png(os.path.join(directory, "checker.png"), TEXELS)
    stage = Usd.Stage.CreateNew(path)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    card = UsdGeom.Mesh.Define(stage, "/World/Card")
    card.CreatePointsAttr([(0, 0, 0), (2, 0, 0), (2, 1, 0), (0, 1, 0)])
    card.CreateFaceVertexCountsAttr([4])
    card.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    card.CreateSubdivisionSchemeAttr("none")
    st = UsdGeom.PrimvarsAPI(card.GetPrim()).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                           UsdGeom.Tokens.faceVarying)
    st.Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    st.SetIndices([0, 1, 2, 3])
    UsdShade.MaterialBindingAPI.Apply(card.GetPrim()).Bind(
        textured_material(stage, "/World/Looks/Srgb", "checker.png"))
    raw = UsdGeom.Mesh.Define(stage, "/World/Raw")
    raw.CreatePointsAttr([(3, 0, 0), (5, 0, 0), (5, 1, 0), (3, 1, 0)])
    raw.CreateFaceVertexCountsAttr([4])
    raw.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    raw.CreateSubdivisionSchemeAttr("none")
    UsdGeom.PrimvarsAPI(raw.GetPrim()).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray,
                                                     UsdGeom.Tokens.vertex).Set([(-0.5, 0), (1.5, 0), (1.5, 1),
                                                                                 (-0.5, 1)])
    UsdShade.MaterialBindingAPI.Apply(raw.GetPrim()).Bind(textured_material(
        stage, "/World/Looks/Raw", "checker.png",
        sourceColorSpace=(Sdf.ValueTypeNames.Token, "raw"),
        wrapS=(Sdf.ValueTypeNames.Token, "clamp"),
        scale=(Sdf.ValueTypeNames.Float4, Gf.Vec4f(0.5, 0.5, 0.5, 1.0)),
        bias=(Sdf.ValueTypeNames.Float4, Gf.Vec4f(0.1, 0.0, 0.0, 0.0))))
    cam = UsdGeom.Camera.Define(stage, "/World/Camera")
    cam.AddTranslateOp().Set(Gf.Vec3d(2.5, 0.5, 10.0))
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateHorizontalApertureAttr(30.0)
    cam.CreateVerticalApertureAttr(6.0)
    stage.GetRootLayer().Save()
    UsdUtils.CreateNewUsdzPackage(path, os.path.splitext(path)[0] + ".usdz")


def big(directory, strands=100_000, points=16):
    """The same strands as .usdc (pinned B-spline, per-vertex widths) and as .hair (thickness array)."""
    os.makedirs(directory, exist_ok=True)
    pts, widths = [], []
    for s in range(strands):
        a, b = 2.0 * math.pi * s / 997.0, 0.5 * math.pi * (s % 991) / 991.0
        n = (math.sin(b) * math.cos(a), math.cos(b), math.sin(b) * math.sin(a))
        for k in range(points):
            t = k / (points - 1)
            pts.append((n[0] * (1 + 0.5 * t), n[1] * (1 + 0.5 * t) - 0.3 * t * t, n[2] * (1 + 0.5 * t)))
            widths.append(0.01 * (1 - 0.5 * t))
    stage = Usd.Stage.CreateNew(os.path.join(directory, "big.usdc"))
    c = UsdGeom.BasisCurves.Define(stage, "/Groom")
    c.CreateBasisAttr("bspline")
    c.CreateWrapAttr("pinned")
    c.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    c.CreateCurveVertexCountsAttr([points] * strands)
    c.CreateWidthsAttr(widths)
    c.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    stage.GetRootLayer().Save()
    with open(os.path.join(directory, "big.hair"), "wb") as f:
        header = struct.pack("<4sIIII f f 3f", b"HAIR", strands, strands * points, 0b10110, points - 1,
                             0.01, 0.0, 1.0, 1.0, 1.0)
        f.write(header + b"usd-test-data big groom".ljust(88, b"\0"))
        f.write(struct.pack("<%df" % (3 * len(pts)), *[x for p in pts for x in p]))
        f.write(struct.pack("<%df" % len(widths), *widths))
        f.write(struct.pack("<%df" % (3 * len(pts)), *([0.5] * (3 * len(pts)))))


def head_groom(directory, strands=5000, points=12):
    """A denser groom on the groom stage's head (a 40x24 UV sphere of radius 1 about (0, 1.5, 0)): strands rooted
    on its top (polar angle up to 80 degrees, a golden-angle spiral; points in the head's space), growing out along
    the normal and drooping;
    pinned B-splines with widths tapering 0.012 -> 0.006; a camera, a sun and a constant sky."""
    os.makedirs(directory, exist_ok=True)
    stage = Usd.Stage.CreateNew(os.path.join(directory, "head-groom.usdc"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    head = UsdGeom.Xform.Define(stage, "/World/Head")
    head.AddTranslateOp().Set(Gf.Vec3d(0.0, 1.5, 0.0))
    mesh = sphere(stage, "/World/Head/Skin", 1.0, 40, 24)
    mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([Gf.Vec3f(0.8, 0.6, 0.5)])
    pts, widths = [], []
    golden = math.pi * (3.0 - math.sqrt(5.0))
    top = 1.0 - math.cos(math.radians(80.0))
    for i in range(strands):
        y = 1.0 - top * (i + 0.5) / strands
        r = math.sqrt(max(0.0, 1.0 - y * y))
        phi = golden * i
        n = (r * math.cos(phi), y, r * math.sin(phi))
        for k in range(points):
            s = 0.9 * k / (points - 1)
            pts.append((n[0] * (1 + 0.5 * s), n[1] * (1 + 0.5 * s) - 0.9 * s * s, n[2] * (1 + 0.5 * s)))
            widths.append(0.012 * (1.0 - 0.5 * k / (points - 1)))
    c = UsdGeom.BasisCurves.Define(stage, "/World/Head/Hair")
    c.CreateTypeAttr("cubic")
    c.CreateBasisAttr("bspline")
    c.CreateWrapAttr("pinned")
    c.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    c.CreateCurveVertexCountsAttr([points] * strands)
    c.CreateWidthsAttr(widths)
    c.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    c.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([Gf.Vec3f(0.35, 0.2, 0.1)])
    cam = UsdGeom.Camera.Define(stage, "/World/Camera")
    cam.AddTranslateOp().Set(Gf.Vec3d(0.0, 2.4, 8.0))
    cam.AddRotateXOp().Set(-8.0)
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateHorizontalApertureAttr(24.0)
    cam.CreateVerticalApertureAttr(24.0)
    sun = UsdLux.DistantLight.Define(stage, "/World/Sun")
    sun.AddRotateXYZOp().Set(Gf.Vec3f(-50.0, 30.0, 0.0))
    sun.CreateIntensityAttr(3.0)
    sky = UsdLux.DomeLight.Define(stage, "/World/Sky")
    sky.CreateColorAttr(Gf.Vec3f(0.3, 0.35, 0.4))
    sky.CreateIntensityAttr(1.0)
    stage.GetRootLayer().Save()


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--big":
        big(sys.argv[2])
        return
    if len(sys.argv) == 3 and sys.argv[1] == "--head":
        head_groom(sys.argv[2])
        return
    os.makedirs(OUT, exist_ok=True)
    groom_stage(os.path.join(OUT, "groom.usda"))
    # The same stage in binary and as a package.
    layer = Sdf.Layer.FindOrOpen(os.path.join(OUT, "groom.usda"))
    layer.Export(os.path.join(OUT, "groom.usdc"))
    UsdUtils.CreateNewUsdzPackage(os.path.join(OUT, "groom.usdc"), os.path.join(OUT, "groom.usdz"))
    bases_stage(os.path.join(OUT, "bases.usda"))
    instancing_stage(os.path.join(OUT, "instancing.usda"))
    textured_stage(os.path.join(OUT, "textured.usda"))


if __name__ == "__main__":
    main()
