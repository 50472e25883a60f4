"""Meshes of two elastic bodies in contact, each meshed on its own (the nodes of the two
sides of the contact do not coincide), for tests/bodies.rs. Needs the Gmsh SDK
(pip install gmsh):

    python3 tests/data/bodies/make_meshes.py --out tests/data/bodies

blocks.msh: two unit-wide blocks stacked at y = 0.5, the lower one (groups "lower",
"lower_top", "bottom", "lower_left") meshed with size 0.09, the upper one ("upper",
"upper_bottom", "top", "upper_left") with size 0.065: the contact patch test.

With --disc H also disc.msh: a half disc of radius 10 (groups "disc", "disc_arc",
"disc_top") on a block 40 x 10 ("block", "block_top", "block_bottom"), both unstructured,
element size H at the contact on the disc and 1.3 H on the block (held-out cases of the
speed study, docs/performance.md).
"""
import argparse
import os

import gmsh


def rectangle(x0, y0, x1, y1, lc, names):
    """A rectangle of its own points and lines; names: surface, bottom, top, left."""
    occ = gmsh.model.geo
    p = [occ.addPoint(x, y, 0, lc) for x, y in [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]]
    lines = [occ.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
    loop = occ.addCurveLoop(lines)
    surface = occ.addPlaneSurface([loop])
    occ.synchronize()
    surf, bottom, top, left = names
    gmsh.model.addPhysicalGroup(2, [surface], name=surf)
    gmsh.model.addPhysicalGroup(1, [lines[0]], name=bottom)
    gmsh.model.addPhysicalGroup(1, [lines[2]], name=top)
    gmsh.model.addPhysicalGroup(1, [lines[3]], name=left)


def blocks(out):
    gmsh.model.add("blocks")
    rectangle(0.0, 0.0, 1.0, 0.5, 0.09, ("lower", "bottom", "lower_top", "lower_left"))
    rectangle(0.0, 0.5, 1.0, 1.0, 0.065, ("upper", "upper_bottom", "top", "upper_left"))
    gmsh.model.mesh.generate(2)
    gmsh.write(os.path.join(out, "blocks.msh"))
    gmsh.model.remove()


def half_disc_on_block(out, lc_disc, lc_block, name):
    """A half disc (radius 10, flat face up at y = 10, centre (0, 10)) resting on a block
    [-20, 20] x [-10, 0] at the origin, both unstructured, finer near the contact."""
    gmsh.model.add(name)
    geo = gmsh.model.geo
    c = geo.addPoint(0, 10, 0, lc_disc * 8)
    left = geo.addPoint(-10, 10, 0, lc_disc * 8)
    right = geo.addPoint(10, 10, 0, lc_disc * 8)
    bottom = geo.addPoint(0, 0, 0, lc_disc)
    arc1 = geo.addCircleArc(left, c, bottom)
    arc2 = geo.addCircleArc(bottom, c, right)
    top = geo.addLine(right, left)
    disc = geo.addPlaneSurface([geo.addCurveLoop([arc1, arc2, top])])
    b = [geo.addPoint(x, y, 0, lc) for x, y, lc in
         [(-20, -10, lc_block * 8), (20, -10, lc_block * 8), (20, 0, lc_block * 4),
          (0, 0, lc_block), (-20, 0, lc_block * 4)]]
    bl = [geo.addLine(b[i], b[(i + 1) % 5]) for i in range(5)]
    block = geo.addPlaneSurface([geo.addCurveLoop(bl)])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(2, [disc], name="disc")
    gmsh.model.addPhysicalGroup(2, [block], name="block")
    gmsh.model.addPhysicalGroup(1, [arc1, arc2], name="disc_arc")
    gmsh.model.addPhysicalGroup(1, [top], name="disc_top")
    gmsh.model.addPhysicalGroup(1, [bl[2], bl[3]], name="block_top")
    gmsh.model.addPhysicalGroup(1, [bl[0]], name="block_bottom")
    gmsh.model.mesh.generate(2)
    gmsh.write(os.path.join(out, name + ".msh"))
    gmsh.model.remove()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=".")
    ap.add_argument("--disc", type=float, default=0.0,
                    help="also write disc.msh, a half disc on a block, with this element size at the contact")
    args = ap.parse_args()
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.RandomSeed", 0.5)
    blocks(args.out)
    if args.disc > 0:
        half_disc_on_block(args.out, args.disc, args.disc * 1.3, "disc")
    gmsh.finalize()


if __name__ == "__main__":
    main()
