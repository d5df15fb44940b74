#!/usr/bin/pvpython
"""Reads a vesica run's FILE.xdmf with ParaView's own readers (its XDMF 2
reader, XDMFReader, and the Xdmf3 one, Xdmf3ReaderS; Debian's
python3-paraview) and FILE.h5 with h5py, and checks them against each other:
every snapshot time, and at each both grids (the nodes as points, the
triangles of the node set in force) with the material positions x, phi and
the flow (velocity, from the second snapshot on) of the file, bit for bit. Not part of make test (ParaView is ~80 MB of
Debian packages, not in make deps): run by hand (docs/results.md, "Reliability and fuzzing").

Usage: pvpython tests/paraview_check.py FILE.xdmf  (exit 0: both readers
read every time and agree; 1 with the reason otherwise)."""
import os
import sys

import h5py
import numpy as np
import paraview
from paraview import servermanager as sm
from paraview import simple
from vtkmodules.util.numpy_support import vtk_to_numpy


def fail(msg):
    print("paraview_check: " + msg)
    sys.exit(1)


def leaves(o):
    """The unstructured grids of a (multi-block or multi-piece) data set."""
    if o.IsA("vtkMultiBlockDataSet") or o.IsA("vtkMultiPieceDataSet"):
        n = o.GetNumberOfBlocks() if o.IsA("vtkMultiBlockDataSet") else o.GetNumberOfPieces()
        for i in range(n):
            b = o.GetBlock(i) if o.IsA("vtkMultiBlockDataSet") else o.GetPiece(i)
            if b is not None:
                yield from leaves(b)
    else:
        yield o


def main():
    if len(sys.argv) != 2:
        fail("usage: pvpython paraview_check.py FILE.xdmf")
    xdmf = os.path.abspath(sys.argv[1])  # Xdmf3 resolves the HDF5 name against its folder
    f = h5py.File(os.path.splitext(xdmf)[0] + ".h5", "r")
    count = int(f["snapshots"].attrs["count"])
    times = [float(f[f"snapshots/{k}"].attrs["t"]) for k in range(count)]
    vecs = 0
    for name in ("XDMFReader", "Xdmf3ReaderS"):
        r = (simple.XDMFReader(FileNames=[xdmf]) if name == "XDMFReader"
             else simple.Xdmf3ReaderS(FileName=[xdmf]))
        if list(r.TimestepValues) != times:
            fail(f"{name}: times {list(r.TimestepValues)}, the file's {times}")
        for k, t in enumerate(times):
            r.UpdatePipeline(t)
            grids = list(leaves(sm.Fetch(r)))
            x, phi = f[f"snapshots/{k}/x"][()], f[f"snapshots/{k}/phi"][()]
            ncells = sorted(g.GetNumberOfCells() for g in grids)
            if len(grids) != 2 or ncells[0] != len(x):
                fail(f"{name}: time {k}: grids of {ncells} cells (want the {len(x)} nodes "
                     "and the triangles)")
            for g in grids:
                p = vtk_to_numpy(g.GetPoints().GetData())
                a = g.GetPointData().GetArray("phi")
                if not np.array_equal(p[:, :2], x) or a is None or \
                        not np.array_equal(vtk_to_numpy(a), phi):
                    fail(f"{name}: time {k}: points or phi differ from /snapshots/{k}")
                # the flow (from the second snapshot on): XDMFReader pads it
                # to 3 components (z = 0: what Glyph takes), Xdmf3 keeps 2
                v, h = g.GetPointData().GetArray("velocity"), f[f"snapshots/{k}"]
                if (v is None) == ("velocity" in h):
                    fail(f"{name}: time {k}: velocity read {v is not None}, "
                         f"in the file {'velocity' in h}")
                if v is not None:
                    v = vtk_to_numpy(v)
                    if not np.array_equal(v[:, :2], h["velocity"][()]) or \
                            (v.shape[1] > 2 and np.any(v[:, 2:] != 0)):
                        fail(f"{name}: time {k}: velocity differs from /snapshots/{k}")
                    vecs += 1
        simple.Delete(r)
    print(f"paraview_check: {os.path.basename(xdmf)}: ParaView {paraview.__version__} "
          f"(XDMFReader, Xdmf3ReaderS) read {count} times, both grids, x and phi (and the "
          f"flow, {vecs} grids) equal to the HDF5 file's (h5py {h5py.__version__})")


main()
