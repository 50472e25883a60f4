"""Generate the Gmsh fixtures used by the tests of src/mesh/gmsh.rs.

Documentation of how the files were made; CI does not run it. Needs the Gmsh SDK:
    pip install gmsh
    python3 tests/data/gmsh/make_fixtures.py [NAME ...]
(NAME: a function below, e.g. bimaterial; none: all of them.)
Writes next to this script. The files are committed so that tests need no Gmsh.
"""

import os

import gmsh

HERE = os.path.dirname(os.path.abspath(__file__))

# (file name, MSH version, binary?)
RECTANGLE_FORMATS = [
    ("rect_v41_ascii.msh", 4.1, 0),
    ("rect_v41_binary.msh", 4.1, 1),
    ("rect_v22_ascii.msh", 2.2, 0),
    ("rect_v22_binary.msh", 2.2, 1),
]


def write(name, version, binary):
    gmsh.option.setNumber("Mesh.MshFileVersion", version)
    gmsh.option.setNumber("Mesh.Binary", binary)
    gmsh.write(os.path.join(HERE, name))


def rectangle():
    """2 x 1 rectangle: four named sides, a named corner point, a named surface."""
    gmsh.model.add("rectangle")
    geo = gmsh.model.geo
    lc = 0.25
    p = [geo.addPoint(x, y, 0, lc) for x, y in [(0, 0), (2, 0), (2, 1), (0, 1)]]
    bottom = geo.addLine(p[0], p[1])
    right = geo.addLine(p[1], p[2])
    top = geo.addLine(p[2], p[3])
    left = geo.addLine(p[3], p[0])
    loop = geo.addCurveLoop([bottom, right, top, left])
    surface = geo.addPlaneSurface([loop])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(1, [bottom], name="bottom")
    gmsh.model.addPhysicalGroup(1, [top], name="top")
    gmsh.model.addPhysicalGroup(1, [left], name="left")
    gmsh.model.addPhysicalGroup(1, [right], name="right")
    gmsh.model.addPhysicalGroup(0, [p[0]], name="corner")
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)
    for name, version, binary in RECTANGLE_FORMATS:
        write(name, version, binary)


def overlap():
    """Tiny square whose bottom side is in two physical line groups ("bottom" and
    "contact"), whose surface is in two physical surfaces ("body", "material"), with
    a line group without a name (tag 7) and a physical point: checks how each format
    stores an element that belongs to several groups (MSH 2.2 repeats it)."""
    gmsh.model.add("overlap")
    geo = gmsh.model.geo
    lc = 0.5
    p = [geo.addPoint(x, y, 0, lc) for x, y in [(0, 0), (1, 0), (1, 1), (0, 1)]]
    lines = [geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
    surface = geo.addPlaneSurface([geo.addCurveLoop(lines)])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(1, [lines[0]], name="bottom")
    gmsh.model.addPhysicalGroup(1, [lines[0], lines[1]], name="contact")
    gmsh.model.addPhysicalGroup(1, [lines[2]], tag=7)
    gmsh.model.addPhysicalGroup(0, [p[2]], name="pin")
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.addPhysicalGroup(2, [surface], name="material")
    gmsh.model.mesh.generate(2)
    write("overlap_v41_ascii.msh", 4.1, 0)
    write("overlap_v22_ascii.msh", 2.2, 0)


def no_groups():
    """Tiny square without any physical group: Gmsh then writes every element."""
    gmsh.model.add("no_groups")
    geo = gmsh.model.geo
    p = [geo.addPoint(x, y, 0, 0.5) for x, y in [(0, 0), (1, 0), (1, 1), (0, 1)]]
    lines = [geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
    geo.addPlaneSurface([geo.addCurveLoop(lines)])
    geo.synchronize()
    gmsh.model.mesh.generate(2)
    write("nogroups_v41_ascii.msh", 4.1, 0)
    write("nogroups_v22_ascii.msh", 2.2, 0)


def quarter_disc():
    """Unstructured quarter disc of radius 1 centred at (0, 1), the lower right
    quarter: the arc "contact" touches y = 0 at the origin (a Hertz-type contact
    test), "axis" is the symmetry line x = 0, "top" the loaded line y = 1."""
    gmsh.model.add("quarter_disc")
    geo = gmsh.model.geo
    centre = geo.addPoint(0, 1, 0, 0.12)
    bottom = geo.addPoint(0, 0, 0, 0.03)
    right = geo.addPoint(1, 1, 0, 0.12)
    arc = geo.addCircleArc(bottom, centre, right)
    top = geo.addLine(right, centre)
    axis = geo.addLine(centre, bottom)
    surface = geo.addPlaneSurface([geo.addCurveLoop([arc, top, axis])])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(1, [arc], name="contact")
    gmsh.model.addPhysicalGroup(1, [axis], name="axis")
    gmsh.model.addPhysicalGroup(1, [top], name="top")
    gmsh.model.addPhysicalGroup(2, [surface], name="body")
    gmsh.model.mesh.generate(2)
    write("quarter_disc_v41_ascii.msh", 4.1, 0)


def bimaterial():
    """2 x 2 square of two bodies stacked along y: "lower" (y < 1) and "upper" (y > 1),
    sharing the interface y = 1 (one set of nodes there). Lines "bottom", "top",
    "left" (both halves), "right"; unstructured triangles, finer in the lower body so
    that the two meshes differ."""
    gmsh.model.add("bimaterial")
    geo = gmsh.model.geo
    pts = [(0, 0, 0.2), (2, 0, 0.2), (2, 1, 0.25), (0, 1, 0.25), (2, 2, 0.35), (0, 2, 0.35)]
    p = [geo.addPoint(x, y, 0, lc) for x, y, lc in pts]
    bottom = geo.addLine(p[0], p[1])
    right_low = geo.addLine(p[1], p[2])
    interface = geo.addLine(p[2], p[3])
    left_low = geo.addLine(p[3], p[0])
    right_up = geo.addLine(p[2], p[4])
    top = geo.addLine(p[4], p[5])
    left_up = geo.addLine(p[5], p[3])
    lower = geo.addPlaneSurface([geo.addCurveLoop([bottom, right_low, interface, left_low])])
    upper = geo.addPlaneSurface([geo.addCurveLoop([-interface, right_up, top, left_up])])
    geo.synchronize()
    gmsh.model.addPhysicalGroup(1, [bottom], name="bottom")
    gmsh.model.addPhysicalGroup(1, [top], name="top")
    gmsh.model.addPhysicalGroup(1, [left_low, left_up], name="left")
    gmsh.model.addPhysicalGroup(1, [right_low, right_up], name="right")
    gmsh.model.addPhysicalGroup(2, [lower], name="lower")
    gmsh.model.addPhysicalGroup(2, [upper], name="upper")
    gmsh.model.mesh.generate(2)
    write("bimaterial_v41_ascii.msh", 4.1, 0)


def main():
    import sys

    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    makers = (rectangle, overlap, no_groups, quarter_disc, bimaterial)
    chosen = [m for m in makers if len(sys.argv) < 2 or m.__name__ in sys.argv[1:]]
    for make in chosen:
        make()
        gmsh.model.remove()
    gmsh.finalize()


if __name__ == "__main__":
    main()
