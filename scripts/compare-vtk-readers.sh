#!/usr/bin/env bash
# VTK 9.1's own readers (Debian's python3-vtk9) against the files evarnode writes: the
# example scene's aorta in each format, compared point by point and face by face with the
# same mesh written as .vtp. docs/FORMATS.md says what the comparison decided.
# Usage: scripts/compare-vtk-readers.sh [BUILD_DIR]   (default: build)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for f in stl ply obj vtk vtp; do "$build/app/evarnode" example --format "$f" --out "$work/$f" > /dev/null 2>&1; done
/usr/bin/python3 - "$work" <<'PY'
import sys
import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy as v2n

def triangles(d):
    c = d.GetPolys()
    return v2n(c.GetConnectivityArray()).reshape(-1, 3) if c.GetNumberOfCells() else np.zeros((0, 3), int)

work = sys.argv[1]
r = vtk.vtkXMLPolyDataReader(); r.SetFileName(f"{work}/vtp/aorta.vtp"); r.Update()
V0, F0 = v2n(r.GetOutput().GetPoints().GetData()), triangles(r.GetOutput())
print("| format | VTK reader | points | vertex order and faces as written | largest difference (mm) | points held as |")
print("| --- | --- | --- | --- | --- | --- |")
for fmt, cls in [("stl", vtk.vtkSTLReader), ("ply", vtk.vtkPLYReader), ("obj", vtk.vtkOBJReader), ("vtk", vtk.vtkPolyDataReader)]:
    rd = cls(); rd.SetFileName(f"{work}/{fmt}/aorta.{fmt}"); rd.Update()
    d = rd.GetOutput()
    V, F = v2n(d.GetPoints().GetData()), triangles(d)
    same = V.shape == V0.shape and F.shape == F0.shape and (F == F0).all()
    err = float(np.abs(V.astype(float) - V0).max()) if same else float("nan")
    print(f"| {fmt} | {cls.__name__} | {V.shape[0]} of {V0.shape[0]} | {'yes' if same else 'no'} | {err:.2g} | {V.dtype} |")
PY
