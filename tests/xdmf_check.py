#!/usr/bin/python3
"""Reads a vesica run's FILE.xdmf with meshio and FILE.h5 with h5py (Debian's
python3-meshio and python3-h5py: readers that share no code with vesica) and
checks them against each other: the time series meshio sees (points,
triangles, and phi and the flow at every snapshot time) is the file's snapshots (meshio's
time series keeps the first time's points: the positions x of later times
are read from the HDF5 file), every group and dataset of the HDF5 file has
the attributes units and description, and the series' status documents its
codes (in its description, and as the enumeration of attribute codes).

Usage: /usr/bin/python3 tests/xdmf_check.py FILE.xdmf  (exit 0: all read
and agree; 1 with the reason otherwise). test_cli test_external_readers
runs it on a small run."""
import os
import sys

import h5py
import meshio
import numpy as np


def fail(msg):
    print("xdmf_check: " + msg)
    sys.exit(1)


def main():
    if len(sys.argv) != 2:
        fail("usage: xdmf_check.py FILE.xdmf")
    xdmf = sys.argv[1]
    h5 = os.path.splitext(xdmf)[0] + ".h5"
    f = h5py.File(h5, "r")
    count = int(f["snapshots"].attrs["count"])
    tri = f["mesh/triangles"][()]
    with meshio.xdmf.TimeSeriesReader(xdmf) as r:
        points, cells = r.read_points_cells()
        if r.num_steps != count:
            fail(f"meshio sees {r.num_steps} times, the file holds {count} snapshots")
        if len(cells) != 1 or cells[0].type != "triangle":
            fail(f"cells: {[c.type for c in cells]} (want one block of triangles)")
        if not np.array_equal(cells[0].data, tri):
            fail("the triangles differ from /mesh/triangles")
        # meshio keeps the first grid's geometry: the initial positions
        if not np.array_equal(points[:, :2], f["snapshots/0/x"][()]):
            fail("the points differ from /snapshots/0/x")
        for k in range(count):
            t, pd, _ = r.read_data(k)
            g = f[f"snapshots/{k}"]
            if t != g.attrs["t"]:
                fail(f"time {k}: {t} against {g.attrs['t']}")
            if "phi" not in pd:
                fail(f"time {k}: no point data phi (has {sorted(pd)})")
            if not np.array_equal(pd["phi"], g["phi"][()]):
                fail(f"time {k}: phi differs from /snapshots/{k}/phi")
            # the flow at the nodes: from the second snapshot on, when held
            if ("velocity" in g) != ("velocity" in pd):
                fail(f"time {k}: velocity in the HDF5 file {'velocity' in g}, "
                     f"in the XDMF file {'velocity' in pd}")
            if "velocity" in g and not np.array_equal(pd["velocity"], g["velocity"][()]):
                fail(f"time {k}: velocity differs from /snapshots/{k}/velocity")
    bare = []

    def described(name, obj):
        if not all(a in obj.attrs for a in ("units", "description")):
            bare.append(name)

    f.visititems(described)
    if not all(a in f.attrs for a in ("units", "description")):
        bare.append("/")
    if bare:
        fail("no units or description on " + ", ".join(bare))
    doc = f["series/status"].attrs["description"].decode()
    if "0 ok" not in doc or "-7 " not in doc:
        fail(f"series/status: its codes are not listed: {doc}")
    codes = h5py.check_enum_dtype(f["series/status"].attrs["codes"].dtype)
    if not codes or codes.get("VES_OK") != 0 or codes.get("VES_ERR_IO") != -7:
        fail(f"series/status: attribute codes is not the enumeration of the codes: {codes}")
    print(
        f"xdmf_check: {os.path.basename(xdmf)}: meshio {meshio.__version__} read {count} times "
        f"of {len(points)} points and {len(tri)} triangles with phi, h5py "
        f"{h5py.__version__} found units and description on every object"
    )


main()
