"""Meshes of two elastic bodies in contact, each meshed on its own (the nodes of the two
sides of the contact do not coincide), for tests/bodies.rs. Needs the Gmsh SDK
(pip install gmsh):

    python3 tests/data/bodies/make_meshes.py --out tests/data/bodies

blocks.msh: two unit-wide blocks stacked at y = 0.5, the lower one (groups "lower",
"lower_top", "bottom", "lower_left") meshed with size 0.09, the upper one ("upper",
"upper_bottom", "top", "upper_left") with size 0.065: the contact patch test.
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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=".")
    args = ap.parse_args()
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.RandomSeed", 0.5)
    blocks(args.out)
    gmsh.finalize()


if __name__ == "__main__":
    main()
