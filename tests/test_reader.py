#!/usr/bin/python3
"""The Python reader python/vesica.py on two small runs of build/vesica (the
TINY settings of tests/cli_test_impl.h): one of 11 steps with a snapshot at
every step (12 snapshots, so HDF5's listing '0', '1', '10', '11', '2', ... is
not their order), one remeshing every 2 steps. Checks the series from
t = 0 (stored, and built for a file without that row), the snapshots'
order and /snapshot_index, the stored interface curves (their area and volume against `vesica
info`, against marching triangles here), the provenance (a restart's too,
and its rows once), the triangles of
a remeshed snapshot, and that meshio.read opens FILE_last.xmf
(docs/manual.md, "XDMF and ParaView").

Run with Debian's python3 (numpy, h5py, meshio): /usr/bin/python3
tests/test_reader.py; prints cmocka's summary lines for tests/run.sh; exit
1 when a check fails. VESICA names the program (default build/vesica, else build-san/vesica)."""
import os
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "python"))

import h5py  # noqa: E402
import numpy as np  # noqa: E402

import py_test_impl  # noqa: E402  (tests/, beside this file)

import vesica  # noqa: E402
from py_test_impl import VESICA  # noqa: E402

TMP = tempfile.mkdtemp(prefix="vesica_reader_")
PLAIN = os.path.join(TMP, "plain.h5")
REMESH = os.path.join(TMP, "remesh.h5")


def info(path):
    p = subprocess.run([VESICA, "info", path], capture_output=True, text=True)
    assert p.returncode == 0, f"vesica info {path}: exit {p.returncode}: {p.stderr}"
    return dict(line.split(" = ", 1) for line in p.stdout.splitlines() if " = " in line)


def setup():
    # 11 steps of 5e-3 at a fixed dt, a snapshot after each
    py_test_impl.tiny_run("[time]\nt_end = 0.055\nadaptive = 0\n[output]\nsnapshot_every = 1\n", PLAIN)
    py_test_impl.tiny_run("[time]\nt_end = 0.03\nadaptive = 0\n[output]\nsnapshot_every = 2\n"
                          "[remesh]\nevery = 2\n", REMESH)


def test_series_from_t0():
    for path in (PLAIN, REMESH):
        r = vesica.load(path)
        with h5py.File(path, "r") as f:
            names = set(f["series"].keys())
            rows = f["series/t"].shape[0]
            E0, A0, V0 = (float(f.attrs[k]) for k in ("E0", "A0", "V0"))
            t_file = f["series/t"][()]
        assert set(r.series) == names, f"columns {sorted(r.series)} against {sorted(names)}"
        # the file stores the initial state's row: step 0 at t = 0, E0, A0, V0
        assert all(len(v) == rows for v in r.series.values())
        s = r.series
        assert s["t"][0] == 0 and s["step"][0] == 0, (s["t"][0], s["step"][0])
        assert (s["E"][0], s["A"][0], s["V"][0]) == (E0, A0, V0)
        assert np.array_equal(s["t"], t_file) and np.array_equal(s["step"], np.arange(rows))
        assert s["dt"][0] == 0 and np.all(np.diff(s["t"]) > 0)
        # vesica info --series shows it too
        p = subprocess.run([VESICA, "info", path, "--series", "0"], capture_output=True, text=True)
        lines = p.stdout.splitlines()
        assert p.returncode == 0 and lines[0].startswith("# step") and len(lines) == rows + 1, p
        assert lines[1].split("\t")[:2] == ["0", "0"], lines[1]
        try:
            df = s.to_pandas()
            assert df.shape == (rows, len(names))
        except ImportError as e:
            assert "pandas" in str(e)
    # a file of an older version (its series from step 1): the row built from E0, A0, V0
    old = os.path.join(TMP, "older.h5")
    shutil.copy(PLAIN, old)
    with h5py.File(old, "r+") as f:
        for c in f["series"]:
            v = f["series"][c][()]
            f["series"][c].resize((len(v) - 1,))
            f["series"][c][...] = v[1:]
        E0 = float(f.attrs["E0"])
    s = vesica.load(old).series
    assert s["step"][0] == 0 and s["t"][0] == 0 and s["E"][0] == E0 and np.isnan(s["dt"][0])
    assert np.array_equal(s["t"], vesica.load(PLAIN).series["t"])


def test_snapshots_in_time_order():
    r = vesica.load(PLAIN)
    with h5py.File(PLAIN, "r") as f:
        listed = list(f["snapshots"].keys())
        count = int(f["snapshots"].attrs["count"])
    assert count == 12, count
    assert listed != sorted(listed, key=int), f"HDF5 lists {listed}: the test shows nothing"
    assert [s.index for s in r.snapshots] == list(range(count))
    t = [s.t for s in r.snapshots]
    assert t[0] == 0 and all(b > a for a, b in zip(t, t[1:])), t
    assert [s.step for s in r.snapshots] == list(range(count))
    assert r.snapshots[0].velocity is None
    last = r.snapshots[-1]
    assert last.velocity.shape == last.x.shape == (len(last.phi), 2)


def index_of(path):
    # /snapshot_index iterated as h5py lists it, and the groups it names in
    # time order, each with its own step and t
    with h5py.File(path, "r") as f:
        count = int(f["snapshots"].attrs["count"])
        rows = [(int(k), int(step), float(t)) for k, step, t in f["snapshot_index"]]
        groups = [(k, int(f["snapshots"][str(k)].attrs["step"]), float(f["snapshots"][str(k)].attrs["t"]))
                  for k in range(count)]
    return rows, groups


def test_snapshot_index():
    # the index lists every snapshot, in time order, for a plain and a
    # remeshed run (its continuation by a restart: test_restart_adds_a_run)
    for path in (PLAIN, REMESH):
        rows, groups = index_of(path)
        assert rows == groups, (path, rows, groups)
        assert all(b[2] > a[2] for a, b in zip(rows, rows[1:])), rows


def test_interface_matches_info():
    # info prints 9 significant digits (agreement at full precision: the
    # same sums, ~1e-15 relative); 1e-6 relative leaves room for that rounding
    for path in (PLAIN, REMESH):
        r, d = vesica.load(path), info(path)
        for s, when in ((r.snapshots[0], "initial"), (r.snapshots[-1], "final")):
            assert s.interface_stored, f"{path}: snapshot {s.index} stores no interface"
            a, v = float(d[f"interface_area_{when}"]), float(d[f"interface_volume_{when}"])
            # one piece, from the upper pole on the axis to the lower one
            assert len(s.interface) == 1, len(s.interface)
            c = s.interface[0]
            assert c[0, 0] == 0 and c[-1, 0] == 0, (c[0], c[-1])
            assert c[0, 1] > 0 > c[-1, 1], (c[0], c[-1])
            # the curve's own sums: pi int r^2 (-dz) and 2 pi int r ds along it
            r_, z_ = c[:, 0], c[:, 1]
            vol = np.pi * np.sum(-np.diff(z_) * (r_[:-1] ** 2 + r_[:-1] * r_[1:] + r_[1:] ** 2) / 3)
            area = np.pi * np.sum((r_[:-1] + r_[1:]) * np.hypot(np.diff(r_), np.diff(z_)))
            da, dv = abs(area / a - 1), abs(vol / v - 1)
            print(f"# {os.path.basename(path)} {when}: area {area:.12g} (info {a:.9g}, {da:.1e}), "
                  f"volume {vol:.12g} (info {v:.9g}, {dv:.1e})")
            assert da < 1e-6 and dv < 1e-6
            # the stored measures are the curve's (the same segments: 1e-12 relative, rounding)
            assert abs(vol / s.interface_volume() - 1) < 1e-12 and abs(area / s.interface_area() - 1) < 1e-12
            # marching triangles here (a file without stored curves) finds the same points
            mine, _ = vesica.interface_curves(s.x, s.phi, s.triangles)
            assert len(mine) == 1 and mine[0].shape == c.shape, (len(mine), mine[0].shape, c.shape)
            assert np.allclose(mine[0], c, rtol=0, atol=1e-12)


def test_provenance():
    for path in (PLAIN, REMESH):
        p = vesica.load(path).provenance
        assert p["commit"] and p["command"].startswith(VESICA) and " run " in p["command"], p
        for lib in ("hdf5", "mumps", "ipopt", "nlopt", "openblas"):
            assert p[lib] and p[lib] != "unknown", (lib, p[lib])
        assert isinstance(p["threads"], int) and p["threads"] >= 1
        assert len(p["runs"]) == 1 and p["runs"][0]["started"].endswith("Z")
        assert all(isinstance(v, str) for k, v in p.items() if k not in ("runs", "threads", "format_version", "setup_seconds"))
        # vesica info --provenance prints the same items
        q = subprocess.run([VESICA, "info", path, "--provenance"], capture_output=True, text=True)
        lines = dict(line.split(" = ", 1) for line in q.stdout.splitlines())
        assert q.returncode == 0 and lines["run.0.commit"] == p["commit"], (q.returncode, q.stdout)
        assert lines["run.0.command"] == p["command"] and int(lines["run.0.threads"]) == p["threads"]


def test_restart_adds_a_run():
    # a restart records its own provenance and appends after the rows it
    # keeps: every step once, the initial row once
    again = os.path.join(TMP, "again.h5")
    shutil.copy(PLAIN, again)
    p = subprocess.run([VESICA, "run", "--restart", again, "--set", "time.t_end=0.065", "--quiet"],
                       capture_output=True, text=True, env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))
    assert p.returncode == 0, p.stderr
    r = vesica.load(again)
    runs = r.provenance["runs"]
    assert len(runs) == 2 and "--restart" in runs[1]["command"] and "--restart" not in runs[0]["command"], runs
    step = r.series["step"]
    assert np.array_equal(step, np.arange(len(step))) and len(step) == 14, step
    assert np.all(np.diff(r.series["t"]) > 0)
    rows, groups = index_of(again)  # the index continued after the restart's snapshot
    assert rows == groups and len(rows) == len(r.snapshots) > 12, (rows, groups)


def test_remeshed_triangles():
    d = info(REMESH)
    assert int(d["remeshings"]) >= 1, d["remeshings"]
    r = vesica.load(REMESH)
    last = r.snapshots[-1]
    k = len(r.remeshes) - 1
    with h5py.File(REMESH, "r") as f:
        tri_k = f[f"remeshes/{k}/triangles"][()]
        tri_0 = f["mesh/triangles"][()]
        step_k = int(f[f"remeshes/{k}"].attrs["step"])
    assert step_k <= last.step and last.mesh == k, (step_k, last.step, last.mesh)
    assert np.array_equal(last.triangles, tri_k)
    assert tri_k.shape != tri_0.shape or not np.array_equal(tri_k, tri_0)
    assert last.triangles.max() < len(last.x) == len(last.phi) == int(d["nodes_final"])
    assert r.snapshots[0].mesh == -1 and np.array_equal(r.snapshots[0].triangles, tri_0)


def test_meshio_reads_last_xmf():
    for path in (PLAIN, REMESH):
        xdmf = path[:-3] + "_last.xmf"
        code = ("import sys, meshio\nm = meshio.read(sys.argv[1])\n"
                "print(len(m.points), len(m.cells[0].data), sorted(m.point_data))")
        p = subprocess.run(["/usr/bin/python3", "-c", code, xdmf], capture_output=True, text=True)
        assert p.returncode == 0, f"meshio.read({xdmf}): exit {p.returncode}: {p.stderr}"
        last = vesica.load(path).snapshots[-1]
        want = f"{len(last.x)} {len(last.triangles)} ['phi', 'velocity']"
        assert p.stdout.strip() == want, (p.stdout, want)


def test_interface_synthetic():
    # phi on a grid of squares cut into triangles: a unit sphere (one piece
    # from pole to pole, area 4 pi, volume 4 pi / 3) and a torus of radii 1
    # and 1/2 (one closed piece, area 2 pi^2, volume pi^2 / 2); the
    # piecewise-linear curve is within O(h^2) of them (h = 0.01: < 1e-3)
    h = 0.01
    r, z = np.meshgrid(np.arange(0, 2 + h / 2, h), np.arange(-2, 2 + h / 2, h), indexing="ij")
    nr, nz = r.shape
    x = np.column_stack([r.ravel(), z.ravel()])
    i = (np.arange(nr - 1)[:, None] * nz + np.arange(nz - 1)[None, :]).ravel()
    tri = np.concatenate([np.column_stack([i, i + nz, i + nz + 1]), np.column_stack([i, i + nz + 1, i + 1])])
    for phi, area, vol, closed in ((1 - x[:, 0] ** 2 - x[:, 1] ** 2, 4 * np.pi, 4 * np.pi / 3, False),
                                   (0.25 - (x[:, 0] - 1) ** 2 - x[:, 1] ** 2, 2 * np.pi ** 2, np.pi ** 2 / 2, True)):
        curves, seg = vesica.interface_curves(x, phi, tri)
        assert len(curves) == 1, len(curves)
        c = curves[0]
        if closed:
            assert np.array_equal(c[0], c[-1])
            # clockwise (negative signed area) from its top, as vesica stores it
            assert np.sum(c[:-1, 0] * c[1:, 1] - c[1:, 0] * c[:-1, 1]) < 0
            assert c[0, 1] == c[:, 1].max()
        else:
            assert c[0, 0] == 0 and c[-1, 0] == 0 and c[0, 1] > 0 > c[-1, 1], (c[0], c[-1])
        a = np.pi * np.sum((seg[:, 0, 0] + seg[:, 1, 0]) * np.hypot(*(seg[:, 1] - seg[:, 0]).T))
        ra, rb, dz = seg[:, 0, 0], seg[:, 1, 0], seg[:, 1, 1] - seg[:, 0, 1]
        v = np.pi * np.sum(dz * (ra * ra + ra * rb + rb * rb) / 3)
        assert abs(a / area - 1) < 1e-3 and abs(v / vol - 1) < 1e-3, (a, area, v, vol)


TESTS = [test_series_from_t0, test_snapshots_in_time_order, test_interface_matches_info,
         test_snapshot_index, test_provenance, test_restart_adds_a_run, test_remeshed_triangles,
         test_meshio_reads_last_xmf, test_interface_synthetic]



sys.exit(py_test_impl.run(TESTS, setup, TMP))
