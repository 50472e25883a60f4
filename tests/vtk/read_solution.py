"""Reads a run's solution.pvtu and its pieces with VTK's own XML readers and prints what
they hold as JSON on stdout, for tests/vtk_reader.rs to check against the run's CSV files.

    python3 tests/vtk/read_solution.py OUT_DIR

Every array is printed as the hex of its bytes in memory (little-endian on the machines
we run on) with its type, so the caller compares values bit for bit without a decimal
round trip. Exit code 3 (and a note on stderr) when the `vtk` package cannot be
imported, so the caller can tell a missing reader from a file VTK refuses.
"""
import json
import os
import sys
import xml.etree.ElementTree as ET

try:
    from vtkmodules.vtkIOXML import (
        vtkXMLPUnstructuredGridReader,
        vtkXMLUnstructuredGridReader,
    )
    from vtkmodules.vtkCommonCore import vtkVersion
except ImportError as e:
    print(f"read_solution.py: cannot import vtk ({e})", file=sys.stderr)
    sys.exit(3)


def raw(a):
    """A VTK array as its type, components and the hex of its values."""
    if a is None:
        return None
    comps = a.GetNumberOfComponents()
    return {
        "type": a.GetDataTypeAsString(),
        "size": a.GetDataTypeSize(),
        "components": comps,
        "component_names": [a.GetComponentName(c) for c in range(comps) if a.HasAComponentName()],
        "hex": bytes(memoryview(a)).hex(),
    }


def arrays(data):
    """Every array of a vtkPointData or vtkCellData, by name, in the file's order."""
    return [dict(name=data.GetArrayName(i), **raw(data.GetArray(i))) for i in range(data.GetNumberOfArrays())]


def grid(reader, path):
    # VTK reports a bad file through its error output and an empty grid, not an exception:
    # the caller checks the counts.
    reader.SetFileName(path)
    reader.Update()
    g = reader.GetOutput()
    pts = g.GetPoints()
    return {
        "points": g.GetNumberOfPoints(),
        "cells": g.GetNumberOfCells(),
        "xyz": raw(pts.GetData()) if pts is not None else None,
        "connectivity": raw(g.GetCells().GetConnectivityArray()),
        "offsets": raw(g.GetCells().GetOffsetsArray()),
        "types": raw(g.GetCellTypesArray()),
        "point_data": arrays(g.GetPointData()),
        "cell_data": arrays(g.GetCellData()),
    }


def main():
    out = sys.argv[1]
    index = os.path.join(out, "solution.pvtu")
    sources = [p.get("Source") for p in ET.parse(index).getroot().iter("Piece")]
    # The index read as ParaView opens it: every piece appended into one grid.
    whole = grid(vtkXMLPUnstructuredGridReader(), index)
    json.dump(
        {
            "vtk_version": vtkVersion.GetVTKVersion(),
            "index": whole,
            "pieces": [grid(vtkXMLUnstructuredGridReader(), os.path.join(out, s)) for s in sources],
        },
        sys.stdout,
    )


main()
