"""Unstructured Gmsh meshes of the two built-in problems at any size, for measuring the
program on meshes it was not tuned to (docs/performance.md, "Unstructured meshes and the order of the file").

    pip install gmsh
    python3 run-scripts/make_meshes.py --case hertz --nodes 1100000 --out DIR
    python3 run-scripts/make_meshes.py --case block --nodes 107000 --out DIR
    python3 run-scripts/make_meshes.py --shuffle DIR/hertz.msh --out DIR/hertz-shuffled.msh

- hertz: the built-in Hertz case (steel quarter cylinder, R = 50 mm, frictionless) on a
  Frontal-Delaunay mesh graded towards the contact point: the size grows linearly with
  the distance to it, from 1/40 of the coarse size there.
- block: the built-in Coulomb block (40 x 10 mm, aluminium) on a uniform
  Frontal-Delaunay mesh.
Each writes DIR/CASE.msh (MSH 4.1, ASCII unless --binary) and DIR/CASE.toml, the
built-in case's physics on that file. `--nodes` is a target: the size is scaled from a
trial mesh, so the count lands within a few percent of it.

`--shuffle FILE` writes a copy of an MSH 4.1 ASCII file with its node tags permuted and
the nodes and elements of each block listed in a random order (seeded by --seed): the same mesh,
the numbering of no mesher, to check that the program's answer and speed do not depend
on the file's order.
"""

import argparse
import math
import os
import random

HERTZ_R = 50.0
BLOCK_W, BLOCK_H = 40.0, 10.0

HERTZ_TOML = """title = "Hertz line contact on an unstructured graded Gmsh mesh"
[mesh]
file = "{msh}"
[material]
young = 210000.0
poisson = 0.3
hypothesis = "plane_strain"
[[dirichlet]]
group = "axis"
ux = 0.0
[[dirichlet]]
group = "top"
uy = -0.4
[contact]
group = "contact"
obstacle_point = [0.0, 0.0]
obstacle_normal = [0.0, 1.0]
friction = "none"
"""

BLOCK_TOML = """title = "Coulomb block on an unstructured Gmsh mesh"
[mesh]
file = "{msh}"
[material]
young = 70000.0
poisson = 0.33
hypothesis = "plane_strain"
[[dirichlet]]
group = "top"
ux = 0.01
uy = -0.02
[contact]
group = "bottom"
obstacle_point = [0.0, 0.0]
obstacle_normal = [0.0, 1.0]
friction = "coulomb"
coefficient = 0.3
"""


def hertz(gmsh, h):
    """Quarter disc centre (0, R): contact arc from (0, 0) to (R, R), top, axis."""
    geo = gmsh.model.geo
    o = geo.addPoint(0, 0, 0)
    c = geo.addPoint(0, HERTZ_R, 0)
    e = geo.addPoint(HERTZ_R, HERTZ_R, 0)
    arc = geo.addCircleArc(o, c, e)
    top = geo.addLine(e, c)
    axis = geo.addLine(c, o)
    surf = geo.addPlaneSurface([geo.addCurveLoop([arc, top, axis])])
    geo.synchronize()
    f = gmsh.model.mesh.field.add("MathEval")
    gmsh.model.mesh.field.setString(f, "F", f"{h / 40} + {0.05 * h / 2.5} * sqrt(x*x + y*y)")
    gmsh.model.mesh.field.setAsBackgroundMesh(f)
    gmsh.model.addPhysicalGroup(1, [arc], name="contact")
    gmsh.model.addPhysicalGroup(1, [top], name="top")
    gmsh.model.addPhysicalGroup(1, [axis], name="axis")
    gmsh.model.addPhysicalGroup(2, [surf], name="steel")


def block(gmsh, h):
    geo = gmsh.model.geo
    pts = [(0, 0), (BLOCK_W, 0), (BLOCK_W, BLOCK_H), (0, BLOCK_H)]
    p = [geo.addPoint(x - BLOCK_W / 2, y, 0, h) for x, y in pts]
    lines = [geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
    surf = geo.addPlaneSurface([geo.addCurveLoop(lines)])
    geo.synchronize()
    f = gmsh.model.mesh.field.add("MathEval")
    gmsh.model.mesh.field.setString(f, "F", f"{h}")
    gmsh.model.mesh.field.setAsBackgroundMesh(f)
    gmsh.model.addPhysicalGroup(1, [lines[0]], name="bottom")
    gmsh.model.addPhysicalGroup(1, [lines[2]], name="top")
    gmsh.model.addPhysicalGroup(2, [surf], name="aluminium")


def mesh(case, h, threads):
    import gmsh

    gmsh.clear()
    gmsh.model.add(case)
    gmsh.option.setNumber("General.NumThreads", threads)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    {"hertz": hertz, "block": block}[case](gmsh, h)
    gmsh.model.mesh.generate(2)
    return len(gmsh.model.mesh.getNodes()[0])


def generate(case, nodes, out, binary, threads):
    import gmsh

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    # A trial at a coarse size, then the size scaled by sqrt(count / target).
    h = 2.0 if case == "hertz" else 0.5
    got = mesh(case, h, threads)
    h *= math.sqrt(got / nodes)
    got = mesh(case, h, threads)
    os.makedirs(out, exist_ok=True)
    msh = f"{case}.msh"
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 1 if binary else 0)
    gmsh.write(os.path.join(out, msh))
    gmsh.finalize()
    text = (HERTZ_TOML if case == "hertz" else BLOCK_TOML).format(msh=msh)
    with open(os.path.join(out, f"{case}.toml"), "w") as f:
        f.write(text)
    print(f"{os.path.join(out, msh)}: {got} nodes")


def shuffle(src, dst, seed):
    """Permutes the node tags and the order of each block's nodes and elements (MSH 4.1 ASCII)."""
    rng = random.Random(seed)
    with open(src) as f:
        lines = f.read().split("\n")
    out, i = [], 0
    while i < len(lines):
        line = lines[i]
        out.append(line)
        i += 1
        if line == "$Nodes":
            head = lines[i].split()
            out.append(lines[i])
            i += 1
            n_blocks, n_nodes = int(head[0]), int(head[1])
            perm = list(range(1, n_nodes + 1))
            rng.shuffle(perm)
            new_tag = {}
            k = 0
            for _ in range(n_blocks):
                out.append(lines[i])
                count = int(lines[i].split()[3])
                i += 1
                tags = lines[i : i + count]
                for t in tags:
                    new_tag[int(t)] = perm[k]
                    k += 1
                # The block's nodes listed in a random order too.
                order = list(range(count))
                rng.shuffle(order)
                out.extend(str(new_tag[int(tags[j])]) for j in order)
                out.extend(lines[i + count + j] for j in order)
                i += 2 * count
        elif line == "$Elements":
            out.append(lines[i])
            n_blocks = int(lines[i].split()[0])
            i += 1
            for _ in range(n_blocks):
                out.append(lines[i])
                count = int(lines[i].split()[3])
                i += 1
                rows = []
                for row in lines[i : i + count]:
                    v = row.split()
                    rows.append(" ".join([v[0]] + [str(new_tag[int(t)]) for t in v[1:]]))
                rng.shuffle(rows)
                out.extend(rows)
                i += count
    with open(dst, "w") as f:
        f.write("\n".join(out))
    print(f"{dst}: node tags and element order shuffled")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--case", choices=["hertz", "block"])
    ap.add_argument("--nodes", type=int, default=100_000)
    ap.add_argument("--out", required=True)
    ap.add_argument("--binary", action="store_true")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--shuffle", metavar="FILE")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    if a.shuffle:
        shuffle(a.shuffle, a.out, a.seed)
    elif a.case:
        generate(a.case, a.nodes, a.out, a.binary, a.threads)
    else:
        ap.error("give --case or --shuffle")


if __name__ == "__main__":
    main()
