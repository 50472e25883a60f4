"""Unstructured Gmsh meshes and case files unlike the built-in cases, for the tests of
the stopping test (tests/tolerance.rs) and the sweep counts of run-scripts/robustness.sh.

Documentation of how the committed files were made; CI does not run it. Needs the Gmsh SDK:
    pip install gmsh
    python3 tests/data/tolerance/make_cases.py                  # the committed test meshes
    python3 tests/data/tolerance/make_cases.py --scale 0.35 --out DIR   # finer (about 12k nodes)
    python3 tests/data/tolerance/make_cases.py --beams --out DIR        # clamped beams 0.2-2 m
    python3 tests/data/tolerance/make_cases.py --slender --out DIR      # held-out slender bodies
    python3 tests/data/tolerance/make_cases.py --heldout --out DIR      # block on a slope, ring, slab, ..., tube, arch, plate
    python3 tests/data/tolerance/make_cases.py --obstacles --out DIR    # circles, a polyline, two bodies
`--scale` multiplies every mesh size; the case files are written next to the meshes.

The cases, each with its own units, group names and foundation:
- cantilever: a steel beam (SI units, plane stress) clamped at one end, sagging under its
  own weight onto a slightly inclined foundation 5e-5 m below; Coulomb 0.5. The
  displacements are rigid-like and large next to what the contact forces cause.
- wall: an aluminium plate (mm, MPa) clamped at its base, pushed by a traction on its
  left flank onto a vertical wall 0.01 mm to its right; Tresca friction.
- disc: a half disc (mm) pressed by its flat top onto a foundation inclined by 3 degrees,
  frictionless, with an off-centre contact (no symmetry).
- wedge: a block under self-weight and a traction, on a foundation inclined by 10 degrees
  with a large friction coefficient (Coulomb 0.9), held by a soft side support.
"""

import argparse
import math
import os

import gmsh

HERE = os.path.dirname(os.path.abspath(__file__))


def write(out, name):
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(os.path.join(out, name))


def polygon(points, lc):
    geo = gmsh.model.geo
    p = [geo.addPoint(x, y, 0, lc) for x, y in points]
    lines = [geo.addLine(p[i], p[(i + 1) % len(p)]) for i in range(len(p))]
    surface = geo.addPlaneSurface([geo.addCurveLoop(lines)])
    return p, lines, surface


def cantilever(scale):
    gmsh.model.add("cantilever")
    _, lines, surface = polygon([(0, 0), (2.0, 0), (2.0, 0.04), (0, 0.04)], 0.008 * scale)
    gmsh.model.geo.synchronize()
    gmsh.model.addPhysicalGroup(1, [lines[0]], name="underside")
    gmsh.model.addPhysicalGroup(1, [lines[3]], name="clamp")
    gmsh.model.addPhysicalGroup(2, [surface], name="steel")
    gmsh.model.mesh.generate(2)


def wall(scale):
    gmsh.model.add("wall")
    pts = [(0, 0), (40, 0), (40, 25), (30, 30), (0, 30)]
    _, lines, surface = polygon(pts, 1.4 * scale)
    gmsh.model.geo.synchronize()
    gmsh.model.addPhysicalGroup(1, [lines[0]], name="base")
    gmsh.model.addPhysicalGroup(1, [lines[1]], name="flank")
    gmsh.model.addPhysicalGroup(1, [lines[4]], name="push")
    gmsh.model.addPhysicalGroup(2, [surface], name="plate")
    gmsh.model.mesh.generate(2)


def disc(scale):
    gmsh.model.add("disc")
    geo = gmsh.model.geo
    R = 20.0
    fine, coarse = 0.35 * scale, 2.5 * scale
    c = geo.addPoint(0, R, 0, coarse)
    left = geo.addPoint(-R, R, 0, coarse)
    right = geo.addPoint(R, R, 0, coarse)
    # The arc is split where the inclined foundation first touches it.
    a = math.radians(3.0)
    touch = geo.addPoint(R * math.sin(a), R - R * math.cos(a), 0, fine)
    arc1 = geo.addCircleArc(left, c, touch)
    arc2 = geo.addCircleArc(touch, c, right)
    top = geo.addLine(right, left)
    surface = geo.addPlaneSurface([geo.addCurveLoop([arc1, arc2, top])])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(1, [arc1, arc2], name="rim")
    gmsh.model.addPhysicalGroup(1, [top], name="flat")
    gmsh.model.addPhysicalGroup(2, [surface], name="disc")
    gmsh.model.mesh.generate(2)


def wedge(scale):
    gmsh.model.add("wedge")
    a = math.radians(10.0)
    # A block whose base lies on the line through the origin inclined by 10 degrees.
    d = (math.cos(a), math.sin(a))
    n = (-math.sin(a), math.cos(a))
    L, H = 2.0, 0.8
    pts = [(0, 0), (L * d[0], L * d[1]), (L * d[0] + H * n[0], L * d[1] + H * n[1]),
           (H * n[0], H * n[1])]
    _, lines, surface = polygon(pts, 0.05 * scale)
    gmsh.model.geo.synchronize()
    gmsh.model.addPhysicalGroup(1, [lines[0]], name="sole")
    gmsh.model.addPhysicalGroup(1, [lines[2]], name="lid")
    gmsh.model.addPhysicalGroup(1, [lines[3]], name="back")
    gmsh.model.addPhysicalGroup(2, [surface], name="block")
    gmsh.model.mesh.generate(2)


BEAM_CASE = """# A clamped steel beam {length} m long, 0.04 m deep (SI units), sagging under its own
# weight onto a flat foundation a hundredth of its free tip deflection below; {law}.
# Made by make_cases.py --beams.
title = "Beam {length} m under self-weight on a foundation"

[mesh]
file = "{mesh}"

[material]
young = 2.1e11
poisson = 0.3
hypothesis = "plane_stress"

[[dirichlet]]
group = "clamp"
ux = 0.0
uy = 0.0

[body_force]
f = [0.0, -77008.5]

[contact]
group = "underside"
obstacle_point = [0.0, {gap:.6e}]
obstacle_normal = [0.0, 1.0]
{friction}
"""


def beams(scale, out):
    """Clamped beams of 0.2, 0.4, 1 and 2 m (the slender-body study): beam_L.msh and beam_L_coulomb.toml, beam_L_none.toml."""
    t, E, weight = 0.04, 2.1e11, 77008.5
    for length in [0.2, 0.4, 1.0, 2.0]:
        gmsh.model.add("beam")
        lc = 0.008 * math.sqrt(length / 2.0) * scale
        _, lines, surface = polygon([(0, 0), (length, 0), (length, t), (0, t)], lc)
        gmsh.model.geo.synchronize()
        gmsh.model.addPhysicalGroup(1, [lines[0]], name="underside")
        gmsh.model.addPhysicalGroup(1, [lines[3]], name="clamp")
        gmsh.model.addPhysicalGroup(2, [surface], name="steel")
        gmsh.model.mesh.generate(2)
        mesh = f"beam_{length}.msh"
        write(out, mesh)
        gmsh.model.remove()
        # Free tip deflection q L^4 / (8 E I) of a cantilever under its own weight.
        tip = weight * t * length**4 / (8 * E * t**3 / 12)
        for name, law, friction in [
            ("coulomb", "Coulomb 0.5", 'friction = "coulomb"\ncoefficient = 0.5'),
            ("none", "frictionless", 'friction = "none"'),
        ]:
            text = BEAM_CASE.format(length=length, law=law, mesh=mesh, gap=-tip / 100,
                                    friction=friction)
            with open(os.path.join(out, f"beam_{length}_{name}.toml"), "w") as f:
                f.write(text)




def strip_mesh(length, depth, lc, name):
    """A rectangle with its groups: under, top, left, right."""
    gmsh.model.add(name)
    _, lines, surface = polygon([(0, 0), (length, 0), (length, depth), (0, depth)], lc)
    gmsh.model.geo.synchronize()
    for line, group in zip(lines, ["under", "right", "top", "left"]):
        gmsh.model.addPhysicalGroup(1, [line], name=group)
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)


def slender(scale, out):
    """Slender bodies unlike the clamped beams the loop's rules were chosen on: other
    supports (simply supported, held only by the contact), loads (traction, tip load),
    units (SI, mm), materials and friction laws, an inclined foundation."""
    cases = []
    # Simply supported aluminium beam (plane strain), sagging under its own weight onto
    # a foundation under its middle, 1/50 of the free mid-span deflection below; Coulomb.
    L, t, E, nu, rho_g = 1.5, 0.03, 70e9, 0.33, 26500.0
    Eeff = E / (1 - nu**2)
    mid = 5 * rho_g * t * L**4 / (384 * Eeff * t**3 / 12)
    cases.append(dict(name="bridge", L=L, t=t, lc=0.006, title="Simply supported beam",
                      what="An aluminium beam on two supports sagging onto a foundation; Coulomb 0.3.",
                      young=E, poisson=nu, hyp="plane_strain",
                      dirichlet='[[dirichlet]]\ngroup = "left"\nux = 0.0\nuy = 0.0\n[[dirichlet]]\ngroup = "right"\nuy = 0.0\n',
                      loads=f"[body_force]\nf = [0.0, {-rho_g}]\n", gap=-mid / 50, n=(0.0, 1.0),
                      friction='friction = "coulomb"\ncoefficient = 0.3'))
    # A thin polymer strip (mm, MPa) clamped at one end, pressed by a traction on its top
    # onto a foundation inclined by 2 degrees; Tresca.
    a = math.radians(2.0)
    cases.append(dict(name="strip", L=400.0, t=8.0, lc=1.6, title="Pressed strip",
                      what="A polymer strip (mm, MPa) clamped at one end, pressed onto an inclined foundation; Tresca.",
                      young=2500.0, poisson=0.4, hyp="plane_stress",
                      dirichlet='[[dirichlet]]\ngroup = "left"\nux = 0.0\nuy = 0.0\n',
                      loads='[[traction]]\ngroup = "top"\nt = [0.0, -0.001]\n', gap=-0.5,
                      n=(math.sin(a), math.cos(a)),
                      friction='friction = "tresca"\nthreshold = 0.0002'))
    # A steel cantilever (mm) bent down by a load on its free end face onto a foundation;
    # Coulomb 0.2.
    cases.append(dict(name="tip", L=800.0, t=20.0, lc=3.0, title="Tip-loaded cantilever",
                      what="A steel cantilever (mm, N, MPa) bent by an end load onto a foundation; Coulomb 0.2.",
                      young=210000.0, poisson=0.3, hyp="plane_stress",
                      dirichlet='[[dirichlet]]\ngroup = "left"\nux = 0.0\nuy = 0.0\n',
                      loads='[[traction]]\ngroup = "right"\nt = [0.0, -200.0]\n', gap=-2.0, n=(0.0, 1.0),
                      friction='friction = "coulomb"\ncoefficient = 0.2'))
    # A timber plank held only at one end face horizontally, lying on a foundation under its
    # own weight (vertically the contact alone holds it); Coulomb 0.6 and frictionless.
    for law, fr in [("coulomb", 'friction = "coulomb"\ncoefficient = 0.6'), ("none", 'friction = "none"')]:
        cases.append(dict(name=f"plank_{law}", mesh="plank", L=3.0, t=0.1, lc=0.012, title="Plank",
                          what="A timber plank resting on a foundation under its own weight, held horizontally at one end.",
                          young=11e9, poisson=0.3, hyp="plane_strain",
                          dirichlet='[[dirichlet]]\ngroup = "left"\nux = 0.0\n',
                          loads="[body_force]\nf = [0.0, -5000.0]\n", gap=-1e-4, n=(0.0, 1.0),
                          friction=fr))
    done = set()
    for c in cases:
        mesh = c.get("mesh", c["name"]) + ".msh"
        if mesh not in done:
            strip_mesh(c["L"], c["t"], c["lc"] * scale, c["name"])
            write(out, mesh)
            gmsh.model.remove()
            done.add(mesh)
        text = HELD_OUT_CASE.format(what=c["what"], flag="slender", title=c["title"], mesh=mesh,
                                    young=c["young"], poisson=c["poisson"], hyp=c["hyp"],
                                    dirichlet=c["dirichlet"], loads=c["loads"], px="0.0",
                                    py=f"{c['gap']:.6e}", nx=c["n"][0], ny=c["n"][1],
                                    friction=c["friction"])
        with open(os.path.join(out, c["name"] + ".toml"), "w") as f:
            f.write(text)


def heldout(scale, out):
    """Held-out cases made after the floors of the held directions' r and the cut step
    of the safeguard were chosen, run once with each binary:
    a steel block in mm with Coulomb 0.8 on a foundation inclined by 15 degrees that
    friction alone holds along the slope, a thin aluminium half ring (mm) standing on its
    outer arc that only the contact holds vertically, and a thin slab in mm on a foundation
    inclined by 3 degrees under its own weight."""
    geo = gmsh.model.geo
    cases = []
    # The block, rotated onto the slope, 0.005 mm above it.
    a = math.radians(15.0)
    d, n = (math.cos(a), math.sin(a)), (-math.sin(a), math.cos(a))
    L, H, gap = 40.0, 20.0, 0.005
    pts = [(gap * n[0], gap * n[1])]
    pts.append((pts[0][0] + L * d[0], pts[0][1] + L * d[1]))
    pts.append((pts[1][0] + H * n[0], pts[1][1] + H * n[1]))
    pts.append((pts[0][0] + H * n[0], pts[0][1] + H * n[1]))
    gmsh.model.add("incline")
    _, lines, surface = polygon(pts, 0.9 * scale)
    gmsh.model.geo.synchronize()
    for line, group in zip(lines, ["under", "right", "top", "left"]):
        gmsh.model.addPhysicalGroup(1, [line], name=group)
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)
    write(out, "incline.msh")
    gmsh.model.remove()
    cases.append(("incline", "A steel block (mm, N, MPa) on a 15-degree slope that friction alone holds along it; Coulomb 0.8.",
                  210000.0, 0.3, "plane_strain", "",
                  f'[[traction]]\ngroup = "top"\nt = [{-0.05 * n[0]:.6e}, {-0.05 * n[1]:.6e}]\n\n[body_force]\nf = [0.0, -7.7e-5]\n',
                  (0.0, 0.0), n, 'friction = "coulomb"\ncoefficient = 0.8'))
    # The half ring: outer radius 50 mm, 3 mm thick, centre 50.01 mm above the foundation.
    R, t, c = 50.0, 3.0, 50.01
    gmsh.model.add("ring")
    lc = 0.6 * scale
    o = geo.addPoint(0, c, 0, lc)
    pts = [geo.addPoint(x, c, 0, lc) for x in (-R, -R + t, R - t, R)]
    bottom_out, bottom_in = geo.addPoint(0, c - R, 0, lc), geo.addPoint(0, c - R + t, 0, lc)
    outer = [geo.addCircleArc(pts[0], o, bottom_out), geo.addCircleArc(bottom_out, o, pts[3])]
    inner = [geo.addCircleArc(pts[2], o, bottom_in), geo.addCircleArc(bottom_in, o, pts[1])]
    right, left = geo.addLine(pts[3], pts[2]), geo.addLine(pts[1], pts[0])
    surface = geo.addPlaneSurface([geo.addCurveLoop(outer + [right] + inner + [left])])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(1, outer, name="under")
    gmsh.model.addPhysicalGroup(1, [left], name="left")
    gmsh.model.addPhysicalGroup(1, [right], name="right")
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)
    write(out, "ring.msh")
    gmsh.model.remove()
    cases.append(("ring", "A thin aluminium half ring (mm) on its outer arc, its end faces pressed down, under its own weight; Coulomb 0.4.",
                  70000.0, 0.33, "plane_stress", '[[dirichlet]]\ngroup = "left"\nux = 0.0\n',
                  '[[traction]]\ngroup = "left"\nt = [0.0, -0.5]\n\n[[traction]]\ngroup = "right"\nt = [0.0, -0.5]\n\n[body_force]\nf = [0.0, -2.65e-5]\n',
                  (0.0, 0.0), (0.0, 1.0), 'friction = "coulomb"\ncoefficient = 0.4'))
    # Its frictionless variant has no unique answer: standing on one node and held along x
    # on the line through its centre only, it can turn about the centre (the run warns).
    cases.append(("ring_none", "The thin half ring, frictionless: free to turn about its centre, an answer that is not unique.",
                  70000.0, 0.33, "plane_stress", '[[dirichlet]]\ngroup = "left"\nux = 0.0\n',
                  '[[traction]]\ngroup = "left"\nt = [0.0, -0.5]\n\n[[traction]]\ngroup = "right"\nt = [0.0, -0.5]\n\n[body_force]\nf = [0.0, -2.65e-5]\n',
                  (0.0, 0.0), (0.0, 1.0), 'friction = "none"', "ring.msh"))
    # The slab: 1000 x 20 mm of concrete, 0.01 mm above a 3-degree slope, held at its
    # upper end face along x.
    a = math.radians(3.0)
    d, n = (math.cos(a), math.sin(a)), (-math.sin(a), math.cos(a))
    L, H, gap = 1000.0, 20.0, 0.01
    pts = [(gap * n[0], gap * n[1])]
    pts.append((pts[0][0] + L * d[0], pts[0][1] + L * d[1]))
    pts.append((pts[1][0] + H * n[0], pts[1][1] + H * n[1]))
    pts.append((pts[0][0] + H * n[0], pts[0][1] + H * n[1]))
    gmsh.model.add("slab")
    _, lines, surface = polygon(pts, 4.0 * scale)
    gmsh.model.geo.synchronize()
    for line, group in zip(lines, ["under", "right", "top", "left"]):
        gmsh.model.addPhysicalGroup(1, [line], name=group)
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)
    write(out, "slab.msh")
    gmsh.model.remove()
    cases.append(("slab", "A thin concrete slab (mm) on a 3-degree slope under its own weight, held along x at its upper end; Coulomb 0.5.",
                  30000.0, 0.2, "plane_strain", '[[dirichlet]]\ngroup = "right"\nux = 0.0\n',
                  "[body_force]\nf = [0.0, -2.4e-5]\n", (0.0, 0.0), n,
                  'friction = "coulomb"\ncoefficient = 0.5'))
    # Made after the normals' floor was lowered for the slab (held out from that choice):
    # a steel sheet (SI) 0.5 m x 5 mm on a 5-degree slope, held along x at its lower end,
    # and an aluminium L-bracket (mm) standing on its foot with a sideways load on its
    # upright.
    a = math.radians(5.0)
    d, n = (math.cos(a), math.sin(a)), (-math.sin(a), math.cos(a))
    L, H, gap = 0.5, 0.005, 2e-6
    pts = [(gap * n[0], gap * n[1])]
    pts.append((pts[0][0] + L * d[0], pts[0][1] + L * d[1]))
    pts.append((pts[1][0] + H * n[0], pts[1][1] + H * n[1]))
    pts.append((pts[0][0] + H * n[0], pts[0][1] + H * n[1]))
    gmsh.model.add("sheet")
    _, lines, surface = polygon(pts, 0.0015 * scale)
    gmsh.model.geo.synchronize()
    for line, group in zip(lines, ["under", "right", "top", "left"]):
        gmsh.model.addPhysicalGroup(1, [line], name=group)
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)
    write(out, "sheet.msh")
    gmsh.model.remove()
    cases.append(("sheet", "A steel sheet (SI) on a 5-degree slope under its own weight, held along x at its lower end; Coulomb 0.3.",
                  2.1e11, 0.3, "plane_stress", '[[dirichlet]]\ngroup = "left"\nux = 0.0\n',
                  "[body_force]\nf = [0.0, -77008.5]\n", (0.0, 0.0), n,
                  'friction = "coulomb"\ncoefficient = 0.3'))
    gmsh.model.add("bracket")
    pts = [(0, 0.002), (120, 0.002), (120, 6.002), (6, 6.002), (6, 80.002), (0, 80.002)]
    _, lines, surface = polygon(pts, 1.2 * scale)
    gmsh.model.geo.synchronize()
    for line, group in zip(lines, ["under", "toe", "foot", "inner", "head", "back"]):
        gmsh.model.addPhysicalGroup(1, [line], name=group)
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)
    write(out, "bracket.msh")
    gmsh.model.remove()
    cases.append(("bracket", "An aluminium L-bracket (mm) on its foot, pressed down on its foot and pushed sideways at its head; Coulomb 0.6.",
                  70000.0, 0.33, "plane_strain", '[[dirichlet]]\ngroup = "toe"\nux = 0.0\n',
                  '[[traction]]\ngroup = "foot"\nt = [0.0, -0.2]\n\n[[traction]]\ngroup = "head"\nt = [0.5, 0.0]\n\n[body_force]\nf = [0.0, -2.65e-5]\n',
                  (0.0, 0.0), (0.0, 1.0), 'friction = "coulomb"\ncoefficient = 0.6'))
    later(cases, scale, out)
    for case in cases:
        name, what, young, nu, hyp, dirichlet, loads, p0, normal, friction = case[:10]
        mesh = case[10] if len(case) > 10 else name + ".msh"
        text = HELD_OUT_CASE.format(what=what, flag="heldout", title=name, mesh=mesh, young=young,
                                   poisson=nu, hyp=hyp, dirichlet=dirichlet, loads=loads,
                                   px=p0[0], py=p0[1], nx=normal[0], ny=normal[1],
                                   friction=friction)
        with open(os.path.join(out, name + ".toml"), "w") as f:
            f.write(text)


def later(cases, scale, out):
    """Made after the free directions' lower r once the statuses settle and the glide of
    a floating body to its first touch: a thin steel tube
    standing on its outer arc, held along x at a top arc where it is pressed (Coulomb,
    Tresca, frictionless), a shallow aluminium arch (SI) on a 0.5-degree slope, and an
    aluminium plate with a hole landing on its corner on a nearly flat foundation. Two of
    them were then used to design a rule, and are held out no more: the frictionless
    tube (the glide) and the plate (free directions settling where every pressed node
    slips); the plate with other coefficients and slopes checked the latter."""
    geo = gmsh.model.geo
    gmsh.model.add("tube")
    R, t, c, lc = 30.0, 2.0, 30.005, 0.5 * scale
    o = geo.addPoint(0, c, 0, lc)
    angles = [0, math.pi / 2, math.pi - 0.1, math.pi + 0.1, 3 * math.pi / 2]

    def ring(r):
        p = [geo.addPoint(r * math.sin(a), c - r * math.cos(a), 0, lc) for a in angles]
        return [geo.addCircleArc(p[i], o, p[(i + 1) % 5]) for i in range(5)]

    outer, inner = ring(R), ring(R - t)
    surface = geo.addPlaneSurface([geo.addCurveLoop(outer), geo.addCurveLoop(inner)])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(1, [outer[0], outer[1], outer[3], outer[4]], name="under")
    gmsh.model.addPhysicalGroup(1, [outer[2]], name="top")
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)
    write(out, "tube.msh")
    gmsh.model.remove()
    for law, fr in [("coulomb", 'friction = "coulomb"\ncoefficient = 0.3'),
                    ("tresca", 'friction = "tresca"\nthreshold = 0.05'),
                    ("none", 'friction = "none"')]:
        what = "A thin steel tube (mm) standing on its outer arc, pressed and held along x at a top arc."
        if law == "none":
            what += " (Then used to design the glide to the first touch.)"
        cases.append((f"tube_{law}", what,
                       210000.0, 0.3, "plane_strain", '[[dirichlet]]\ngroup = "top"\nux = 0.0\n',
                       '[[traction]]\ngroup = "top"\nt = [0.0, -2.0]\n', (0.0, 0.0), (0.0, 1.0), fr,
                       "tube.msh"))
    # The arch: underside an arc of radius 5 m and chord 1 m, 0.02 m deep.
    gmsh.model.add("arch")
    R, half, depth, lc = 5.0, 0.5, 0.02, 0.004 * scale
    cy = R + 1e-5
    o = geo.addPoint(0, cy, 0, lc)
    a = math.asin(half / R)

    def arc(r):
        return [geo.addPoint(x * r * math.sin(a), cy - r * math.cos(x * a), 0, lc) for x in (-1, 0, 1)]

    b, u = arc(R), arc(R - depth)
    under = [geo.addCircleArc(b[0], o, b[1]), geo.addCircleArc(b[1], o, b[2])]
    right = geo.addLine(b[2], u[2])
    top = [geo.addCircleArc(u[2], o, u[1]), geo.addCircleArc(u[1], o, u[0])]
    left = geo.addLine(u[0], b[0])
    surface = geo.addPlaneSurface([geo.addCurveLoop(under + [right] + top + [left])])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(1, under, name="under")
    gmsh.model.addPhysicalGroup(1, [left], name="left")
    gmsh.model.addPhysicalGroup(1, top, name="top")
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)
    write(out, "arch.msh")
    gmsh.model.remove()
    s = math.radians(0.5)
    cases.append(("arch", "A shallow aluminium arch (SI) on a 0.5-degree slope, under its own weight and a load on its top, held along x at its left end; Coulomb 0.6.",
                  7.0e10, 0.33, "plane_stress", '[[dirichlet]]\ngroup = "left"\nux = 0.0\n',
                  '[[traction]]\ngroup = "top"\nt = [0.0, -200.0]\n\n[body_force]\nf = [0.0, -26500.0]\n',
                  (0.0, -0.0002), (math.sin(s), math.cos(s)), 'friction = "coulomb"\ncoefficient = 0.6'))
    # The plate: 60 x 30 mm with a hole of radius 8, 0.05 mm above a foundation sloped
    # by 0.03 degrees, held along x at its top, where it is pressed.
    gmsh.model.add("holed")
    lc, y0 = 1.0 * scale, 0.05
    p = [geo.addPoint(x, y, 0, lc) for x, y in [(0, y0), (60, y0), (60, y0 + 30), (0, y0 + 30)]]
    lines = [geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
    c = geo.addPoint(30, y0 + 15, 0, lc)
    q = [geo.addPoint(30 + 8 * math.cos(k * math.pi / 2), y0 + 15 + 8 * math.sin(k * math.pi / 2), 0, lc)
         for k in range(4)]
    hole = [geo.addCircleArc(q[i], c, q[(i + 1) % 4]) for i in range(4)]
    surface = geo.addPlaneSurface([geo.addCurveLoop(lines), geo.addCurveLoop(hole)])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(1, [lines[0]], name="under")
    gmsh.model.addPhysicalGroup(1, [lines[2]], name="top")
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)
    write(out, "holed.msh")
    gmsh.model.remove()
    s = math.radians(0.03)
    cases.append(("holed", "An aluminium plate (mm) with a hole, landing on its corner on a nearly flat foundation; Coulomb 0.9. (Then used to design the settling of free directions where every pressed node slips.)",
                  70000.0, 0.33, "plane_strain", '[[dirichlet]]\ngroup = "top"\nux = 0.0\n',
                  '[[traction]]\ngroup = "top"\nt = [0.0, -1.0]\n\n[body_force]\nf = [0.0, -2.65e-5]\n',
                  (0.0, 0.0), (-math.sin(s), math.cos(s)), 'friction = "coulomb"\ncoefficient = 0.9'))


HELD_OUT_CASE = """# {what}
# Made by make_cases.py --{flag} (a held-out check of the loop's sweep counts: not used
# to choose any of its rules).
title = "{title}"

[mesh]
file = "{mesh}"

[material]
young = {young}
poisson = {poisson}
hypothesis = "{hyp}"
{dirichlet}
{loads}
[contact]
group = "under"
obstacle_point = [{px}, {py}]
obstacle_normal = [{nx:.12f}, {ny:.12f}]
{friction}
"""


def obstacles(scale, out):
    """Held-out cases made after every rule of the loop was chosen, on the contact kinds
    the cases above leave out: circles, a polyline and two elastic bodies. Each case file
    is written whole here; the tests use the pin and the stack of `--scale 2`.
    - roller: a steel half disc (SI) on a rigid roller (circle), pressed and moved along x
      at its lid; Coulomb 0.3; it stands on one node.
    - pin: a steel annulus (mm) in a hole 0.01 mm wider (circle, body inside), its bore
      driven down and sideways: a wide conforming contact; Coulomb 0.2.
    - groove: an aluminium disc (mm, plane stress) in a V groove (polyline, walls at 40
      degrees), under its own weight and a load on its upper rim; Coulomb 0.25.
    - kink: a steel beam (SI, plane stress, 1 m x 30 mm) clamped at one end, sagging under
      its own weight and a load onto a foundation that is flat and then rises by 15 um
      over 0.6 m (polyline); Tresca.
    - stack: a steel block 0.001 mm above a concrete slab clamped at its base (mm; two
      bodies), pressed down and pushed sideways; Coulomb 0.5 between them.
    - hertz2: an aluminium half disc on a steel block (two bodies), pressed and moved along
      x at its lid; Coulomb 0.3.
    - pad: a pad of E = 5 MPa pressed 0.5 mm into a steel plate (two bodies, E ratio
      42000); frictionless.
    Made after those, with the same aim:
    - corner: an aluminium block (mm) pushed into a corner: a floor (Coulomb 0.3) and a
      wall (Tresca), two contacts that share the corner node.
    - ridge: a steel strip (SI, plane stress, 0.4 m x 4 mm) pressed onto a ridge (a
      polyline falling 0.5 degrees to each side), held along x at its left end face only:
      balanced on the ridge, the contact alone holds it up; Coulomb 0.4. The tests use it
      at `--scale 1`.
    - pinplate: a steel disc in a hole 0.02 mm wider of an aluminium plate clamped at its
      base (two bodies, curved and conforming), the disc's centre moved down 0.05 mm;
      Coulomb 0.2."""
    geo = gmsh.model.geo

    def half_disc(cx, cy, radius, lc):
        o = geo.addPoint(cx, cy, 0, lc)
        a, b, c = (geo.addPoint(cx + x, cy + y, 0, lc) for x, y in [(-radius, 0), (0, -radius), (radius, 0)])
        arcs = [geo.addCircleArc(a, o, b), geo.addCircleArc(b, o, c)]
        lid = geo.addLine(c, a)
        return arcs, lid, geo.addPlaneSurface([geo.addCurveLoop(arcs + [lid])])

    def circle(o, cy, radius, lc):
        q = [geo.addPoint(radius * math.cos(k * math.pi / 2), cy + radius * math.sin(k * math.pi / 2), 0, lc)
             for k in range(4)]
        return [geo.addCircleArc(q[k], o, q[(k + 1) % 4]) for k in range(4)]

    def mesh(name, lines, surfaces):
        geo.synchronize()
        for group, entities in lines.items():
            gmsh.model.addPhysicalGroup(1, entities, name=group)
        for group, entities in surfaces.items():
            gmsh.model.addPhysicalGroup(2, entities, name=group)
        gmsh.model.mesh.generate(2)
        write(out, name + ".msh")
        gmsh.model.remove()

    def case(name, title, body):
        with open(os.path.join(out, name + ".toml"), "w") as f:
            f.write(f'# Made by make_cases.py --obstacles (held out: not used to choose any rule of the loop).\n'
                    f'title = "{title}"\n\n[mesh]\nfile = "{name}.msh"\n\n{body}')

    gmsh.model.add("roller")
    arcs, lid, s = half_disc(0.0, 0.05 + 1e-5, 0.05, 0.0012 * scale)
    mesh("roller", {"rim": arcs, "lid": [lid]}, {"disc": [s]})
    case("roller", "A steel half disc on a rigid roller", """[material]
young = 2.1e11
poisson = 0.3

[[dirichlet]]
group = "lid"
ux = 1e-6

[[traction]]
group = "lid"
t = [0.0, -2.0e6]

[[contact]]
slave = "rim"
obstacle = { type = "circle", centre = [0.0, -0.1], radius = 0.1 }
friction = "coulomb"
coefficient = 0.3
""")

    gmsh.model.add("pin")
    lc = 0.35 * scale
    o = geo.addPoint(0, 0, 0, lc)
    skin, bore = circle(o, 0.0, 10.0, lc), circle(o, 0.0, 4.0, lc)
    s = geo.addPlaneSurface([geo.addCurveLoop(skin), geo.addCurveLoop(bore)])
    mesh("pin", {"skin": skin, "bore": bore}, {"pin": [s]})
    case("pin", "A pin driven into the side of its hole", """[material]
young = 200000.0
poisson = 0.29

[[dirichlet]]
group = "bore"
ux = 0.004
uy = -0.02

[[contact]]
slave = "skin"
obstacle = { type = "circle", centre = [0.0, 0.0], radius = 10.01, body = "inside" }
friction = "coulomb"
coefficient = 0.2
""")

    gmsh.model.add("groove")
    radius, wall, reach = 20.0, math.radians(40.0), 60.0
    cy = (radius + 0.005) / math.cos(wall)
    lc = 0.7 * scale
    arcs = circle(geo.addPoint(0, cy, 0, lc), cy, radius, lc)
    s = geo.addPlaneSurface([geo.addCurveLoop(arcs)])
    mesh("groove", {"lower_rim": arcs[2:], "upper_rim": arcs[:2]}, {"disc": [s]})
    rise = reach * math.tan(wall)
    case("groove", "An aluminium disc in a V groove", f"""[material]
young = 70000.0
poisson = 0.33
hypothesis = "plane_stress"

[[traction]]
group = "upper_rim"
t = [0.3, -1.5]

[body_force]
f = [0.0, -2.7e-5]

[[contact]]
slave = "lower_rim"
obstacle = {{ type = "polyline", points = [[{-reach}, {rise!r}], [0.0, 0.0], [{reach}, {rise!r}]] }}
friction = "coulomb"
coefficient = 0.25
""")

    gmsh.model.add("kink")
    lines, s = polygon([(0, 0), (1.0, 0), (1.0, 0.03), (0, 0.03)], 0.004 * scale)[1:]
    mesh("kink", {"sole": [lines[0]], "root": [lines[3]]}, {"beam": [s]})
    case("kink", "A steel beam sagging onto a kinked foundation", """[material]
young = 2.1e11
poisson = 0.3
hypothesis = "plane_stress"

[[dirichlet]]
group = "root"
ux = 0.0
uy = 0.0

[[traction]]
group = "sole"
t = [0.0, -800.0]

[body_force]
f = [0.0, -77000.0]

[[contact]]
slave = "sole"
obstacle = { type = "polyline", points = [[-0.1, -2e-5], [0.6, -2e-5], [1.2, -5e-6]] }
friction = "tresca"
threshold = 40.0
""")

    gmsh.model.add("stack")
    slab, s1 = polygon([(0, 0), (60, 0), (60, 20), (0, 20)], 1.0 * scale)[1:]
    block, s2 = polygon([(15, 20.001), (45, 20.001), (45, 35.001), (15, 35.001)], 0.7 * scale)[1:]
    mesh("stack", {"base": [slab[0]], "deck": [slab[2]], "foot": [block[0]], "crown": [block[2]],
                   "flank": [block[3]]}, {"slab": [s1], "block": [s2]})
    case("stack", "A steel block on a concrete slab, pushed sideways", """[[material]]
group = "slab"
young = 30000.0
poisson = 0.2

[[material]]
group = "block"
young = 210000.0
poisson = 0.3

[[dirichlet]]
group = "base"
ux = 0.0
uy = 0.0

[[traction]]
group = "crown"
t = [0.0, -20.0]

[[traction]]
group = "flank"
t = [6.0, 0.0]

[[contact]]
slave = "foot"
master = "deck"
friction = "coulomb"
coefficient = 0.5
""")

    gmsh.model.add("hertz2")
    arcs, lid, s2 = half_disc(0.0, 50.002, 20.0, 0.6 * scale)
    block, s1 = polygon([(-40, 0), (40, 0), (40, 30), (-40, 30)], 1.2 * scale)[1:]
    mesh("hertz2", {"rim": arcs, "lid": [lid], "ground": [block[0]], "face": [block[2]]},
         {"block": [s1], "disc": [s2]})
    case("hertz2", "An aluminium half disc on a steel block", """[[material]]
group = "block"
young = 210000.0
poisson = 0.3

[[material]]
group = "disc"
young = 70000.0
poisson = 0.33

[[dirichlet]]
group = "ground"
ux = 0.0
uy = 0.0

[[dirichlet]]
group = "lid"
ux = 0.002

[[traction]]
group = "lid"
t = [0.0, -60.0]

[[contact]]
slave = "rim"
master = "face"
friction = "coulomb"
coefficient = 0.3
""")

    gmsh.model.add("pad")
    plate, s1 = polygon([(0, 0), (50, 0), (50, 5), (0, 5)], 0.6 * scale)[1:]
    pad, s2 = polygon([(10, 5.0005), (40, 5.0005), (40, 15.0005), (10, 15.0005)], 0.5 * scale)[1:]
    mesh("pad", {"base": [plate[0]], "plate_top": [plate[2]], "pad_sole": [pad[0]], "pad_top": [pad[2]]},
         {"plate": [s1], "pad": [s2]})
    case("pad", "A soft pad pressed into a steel plate", """[[material]]
group = "plate"
young = 210000.0
poisson = 0.3

[[material]]
group = "pad"
young = 5.0
poisson = 0.45

[[dirichlet]]
group = "base"
ux = 0.0
uy = 0.0

[[dirichlet]]
group = "pad_top"
ux = 0.0
uy = -0.5

[[contact]]
slave = "pad_sole"
master = "plate_top"
friction = "none"
""")

    gmsh.model.add("corner")
    sides, s = polygon([(0.003, 0.002), (40, 0.002), (40, 25), (0.003, 25)], 0.5 * scale)[1:]
    mesh("corner", dict(zip(["bottom", "right", "top", "left"], ([x] for x in sides))), {"block": [s]})
    case("corner", "An aluminium block pushed into a corner", """[material]
young = 70000.0
poisson = 0.33

[[traction]]
group = "right"
t = [-3.0, 0.0]

[[traction]]
group = "top"
t = [0.0, -5.0]

[[contact]]
slave = "bottom"
obstacle = { type = "line", point = [0.0, 0.0], normal = [0.0, 1.0] }
friction = "coulomb"
coefficient = 0.3

[[contact]]
slave = "left"
obstacle = { type = "line", point = [0.0, 0.0], normal = [1.0, 0.0] }
friction = "tresca"
threshold = 0.5
""")

    gmsh.model.add("ridge")
    sides, s = polygon([(-0.2, 2e-5), (0.2, 2e-5), (0.2, 2e-5 + 0.004), (-0.2, 2e-5 + 0.004)],
                       0.0008 * scale)[1:]
    mesh("ridge", dict(zip(["under", "rend", "top", "lend"], ([x] for x in sides))), {"strip": [s]})
    drop = -0.3 * math.tan(math.radians(0.5))
    case("ridge", "A steel strip balanced on a ridge", f"""[material]
young = 2.1e11
poisson = 0.3
hypothesis = "plane_stress"

[[dirichlet]]
group = "lend"
ux = 0.0

[[traction]]
group = "top"
t = [0.0, -15000.0]

[[contact]]
slave = "under"
obstacle = {{ type = "polyline", points = [[-0.3, {drop!r}], [0.0, 0.0], [0.3, {drop!r}]] }}
friction = "coulomb"
coefficient = 0.4
""")

    gmsh.model.add("pinplate")
    lc = 0.5 * scale
    o = geo.addPoint(0, 0, 0, lc)
    disc, hole = circle(o, 0.0, 8.0, lc), circle(o, 0.0, 8.02, 0.8 * lc)
    plate = polygon([(-30, -30), (30, -30), (30, 30), (-30, 30)], 2.5 * lc)
    gmsh.model.geo.remove([(2, plate[2])])
    s1 = geo.addPlaneSurface([geo.addCurveLoop(plate[1]), geo.addCurveLoop(hole)])
    s2 = geo.addPlaneSurface([geo.addCurveLoop(disc)])
    geo.synchronize()
    gmsh.model.mesh.embed(0, [o], 2, s2)
    gmsh.model.addPhysicalGroup(0, [o], name="centre")
    mesh("pinplate", {"disc_rim": disc, "hole_rim": hole, "plate_bottom": [plate[1][0]]},
         {"plate": [s1], "disc": [s2]})
    case("pinplate", "A steel disc pulled down in an aluminium plate's hole", """[[material]]
group = "plate"
young = 70000.0
poisson = 0.33

[[material]]
group = "disc"
young = 210000.0
poisson = 0.3

[[dirichlet]]
group = "plate_bottom"
ux = 0.0
uy = 0.0

[[dirichlet]]
group = "centre"
ux = 0.0
uy = -0.05

[[contact]]
slave = "hole_rim"
master = "disc_rim"
friction = "coulomb"
coefficient = 0.2
""")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--out", default=HERE)
    ap.add_argument("--beams", action="store_true",
                    help="write the clamped beams of the slender-body study instead")
    ap.add_argument("--slender", action="store_true",
                    help="write the held-out slender bodies instead")
    ap.add_argument("--heldout", action="store_true",
                    help="write the held-out cases (block on a slope, half ring, slab, sheet, bracket, tube, arch, holed plate) instead")
    ap.add_argument("--obstacles", action="store_true",
                    help="write the held-out cases against circles, polylines, two contacts and another body instead")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    if args.beams or args.slender or args.heldout or args.obstacles:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("Mesh.Algorithm", 6)
        make = (beams if args.beams else slender if args.slender else heldout if args.heldout
                else obstacles)
        make(args.scale, args.out)
        gmsh.finalize()
        return
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    for name, make in [("cantilever", cantilever), ("wall", wall), ("disc", disc),
                       ("wedge", wedge)]:
        make(args.scale)
        write(args.out, name + ".msh")
        gmsh.model.remove()
    gmsh.finalize()


if __name__ == "__main__":
    main()
