#!/usr/bin/python3
"""A PLUS sequence exported by `evarnode export` read by a third party: VTK's own MetaImage
reader (vtkMetaImageReader, the MetaIO library under 3D Slicer's and PLUS's image readers).

Usage: plus_export_in_vtk.py EVARNODE WORKDIR

Makes a small simulated session, exports it, and checks what VTK reads against the
session's own frames (read by VTK's PNG reader): the size, the spacing, the pixel type and
every pixel, and the per-frame timestamps a sequence importer keys frames by.
"""
import csv
import json
import os
import shutil
import subprocess
import sys

try:
    import numpy as np
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy
except ImportError as e:  # the test command installs python3-vtk9 (scripts/install-deps.sh)
    sys.exit(f"plus_export_in_vtk: {e}: install python3-vtk9 and python3-numpy")


def fail(what):
    sys.exit(f"plus_export_in_vtk: {what}")


def main():
    evarnode, work = sys.argv[1], sys.argv[2]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    session, mha = os.path.join(work, "session"), os.path.join(work, "run.seq.mha")
    subprocess.run([evarnode, "sim", "session", "--seed", "5", "--out", session, "--detector-px", "96",
                    "--fluoro-seconds", "0.4", "--no-progress"], check=True)
    subprocess.run([evarnode, "export", session, "--out", mha, "--no-progress"], check=True)

    reader = vtk.vtkMetaImageReader()
    reader.SetFileName(mha)
    reader.Update()
    if reader.GetErrorCode() != 0:
        fail(f"vtkMetaImageReader error {reader.GetErrorCode()} on {mha}")
    image = reader.GetOutput()
    cols, rows, frames = image.GetDimensions()
    with open(os.path.join(session, "session.json")) as f:
        detector = json.load(f)["detector"]
    if (cols, rows) != (detector["cols"], detector["rows"]):
        fail(f"VTK reads {cols} x {rows} pixels, the session's detector is {detector['cols']} x {detector['rows']}")
    spacing = image.GetSpacing()
    if abs(spacing[0] - detector["col_spacing_mm"]) > 1e-9 or abs(spacing[1] - detector["row_spacing_mm"]) > 1e-9:
        fail(f"VTK reads spacing {spacing[:2]}, the detector's is {detector['col_spacing_mm']}, {detector['row_spacing_mm']}")
    if image.GetScalarType() != vtk.VTK_UNSIGNED_SHORT or image.GetNumberOfScalarComponents() != 1:
        fail(f"VTK reads {image.GetScalarTypeAsString()} x {image.GetNumberOfScalarComponents()}, not one unsigned short")

    with open(os.path.join(session, "frames", "index.csv")) as f:
        index = list(csv.DictReader(f))
    if frames != len(index):
        fail(f"VTK reads {frames} frames, the session has {len(index)}")
    volume = vtk_to_numpy(image.GetPointData().GetScalars()).reshape(frames, rows, cols)
    for k, row in enumerate(index):
        png = vtk.vtkPNGReader()
        png.SetFileName(os.path.join(session, "frames", row["file"]))
        png.Update()
        pixels = vtk_to_numpy(png.GetOutput().GetPointData().GetScalars()).reshape(rows, cols)
        # vtkPNGReader turns rows to VTK's bottom-up order; MetaImage keeps the file's.
        if not np.array_equal(pixels[::-1, :], volume[k]):
            fail(f"frame {k} ({row['file']}): VTK's pixels differ from the session's PNG")

    # The per-frame fields, as a key = value parser (PLUS's, SlicerIGSIO's) reads them.
    with open(mha, "rb") as f:
        header = f.read(1 << 20).split(b"ElementDataFile", 1)[0].decode("ascii")
    stamps = [float(line.split("=", 1)[1]) for line in header.splitlines() if "_Timestamp =" in line]
    if len(stamps) != frames:
        fail(f"{len(stamps)} Seq_Frame*_Timestamp fields for {frames} frames")
    keys = [round(t, 3) for t in stamps]  # Slicer's importer keys a frame by its time to the millisecond
    if any(b <= a for a, b in zip(keys, keys[1:])):
        fail("two frames share a millisecond timestamp (an importer would merge them)")
    print(f"VTK {vtk.vtkVersion.GetVTKVersion()} read {frames} frames of {cols} x {rows}, every pixel as in the session")


if __name__ == "__main__":
    main()
