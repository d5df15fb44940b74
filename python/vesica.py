"""Read a vesica run's output file (FILE.h5) into numpy arrays.

Needs numpy and h5py only (Debian: python3-numpy, python3-h5py); pandas is
used by Series.to_pandas() when it is importable. Importable without
installation: put the folder python/ of the repository on sys.path (or
PYTHONPATH) and

    import vesica
    run = vesica.load("run.h5")
    t, E = run.series["t"], run.series["E"]        # E* against t*, from t = 0
    last = run.snapshots[-1]                        # the last stored state
    for r_z in last.interface:                      # the phi = 0 curve(s)
        r, z = r_z.T
    last.interface_area(), last.interface_volume()  # as `vesica info` computes them
    run.provenance["commit"]                        # what made the file

The layout read here is docs/manual.md, "Output format" (and
solver/app/io.h). Lengths are in R0, times in t*, energies in k.
"""

import math

import h5py
import numpy as np

__all__ = ["load", "load_study", "Run", "Series", "Snapshot", "interface_curves"]


_SERIES_ORDER = ["t", "dt", "E", "A", "V", "V_target", "lambda_A", "lambda_V", "c0", "iterations",
                 "f_evals", "g_evals", "h_evals", "violation", "solve_seconds", "wall_seconds",
                 "retries", "status", "reconnections", "factorizations"]


def _text(v):
    """An attribute value with bytes decoded (UTF-8) and numpy scalars made Python's."""
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    if isinstance(v, np.ndarray) and v.dtype.kind in "SO":
        return [_text(x) for x in v.tolist()]
    if isinstance(v, np.generic):
        return v.item()
    return v


def _open(path):
    # a run still being written holds the file open: read without HDF5's file
    # lock where this h5py offers the choice (vesica info reads it too)
    try:
        return h5py.File(path, "r", locking=False)
    except (TypeError, ValueError):  # an h5py or HDF5 without the choice
        return h5py.File(path, "r")


class Series(dict):
    """The series of a run: column name -> 1-D numpy array, one entry per row.

    Every column of the file's /series (t, dt, E, A, V, V_target, lambda_A,
    lambda_V, c0, iterations, f_evals, g_evals, h_evals, violation,
    solve_seconds, wall_seconds, retries, status, reconnections,
    factorizations, step; docs/manual.md, "The series").

    The first row is the initial state at t = 0 (step 0). A file of this
    version stores it (its columns that describe a step, dt, iterations,
    evaluations, ..., are 0 there); for an older file, whose series starts at
    step 1, it is built from the root attributes E0, A0, V0 (E = E0, A = A0,
    V = V_target = V0) and snapshot 0's state (c0, lambda_A, lambda_V), the
    columns that describe a step NaN, wall_seconds and reconnections 0.
    Every column is float. `file_rows` holds the file's rows as stored, with
    their own types. Only complete rows are read (a run killed during an
    append leaves some columns one row longer: the shortest length counts).
    """

    def __init__(self, columns, file_rows):
        super().__init__(columns)
        self.file_rows = file_rows

    def __len__(self):
        return len(self["t"]) if "t" in self else 0

    @property
    def columns(self):
        return list(self.keys())

    def to_pandas(self):
        """The series as a pandas DataFrame (ImportError when pandas is not installed)."""
        try:
            import pandas as pd
        except ImportError as e:
            raise ImportError("Series.to_pandas needs pandas (python3-pandas)") from e
        return pd.DataFrame(dict(self))


class Snapshot:
    """One stored state of a run: time t (t*), step, and its data.

    x: n x 2 positions (r, z) of the material at the nodes (R0; the
    coefficients y for a file of format 1); phi: n values; velocity: n x 2
    flow at the nodes (R0 per t*) or None when not stored (snapshot 0, a
    state without a last step); y: the nodal coefficients; triangles: ntri x
    3 node indices of the triangulation the snapshot's node set belongs to
    (/mesh/triangles, or after a remeshing that of the last remeshing made
    at or before its step, /remeshes/<k>/triangles); mesh: -1 for the
    initial node set, else that k. attrs: the group's attributes.
    """

    def __init__(self, run, index, attrs, mesh):
        self._run = run
        self.index = index  # k of /snapshots/<k>
        self.attrs = attrs
        self.t = float(attrs["t"])
        self.step = int(attrs["step"])
        self.mesh = mesh
        self._cache = {}
        self._curves = None

    def __repr__(self):
        return f"<vesica.Snapshot {self.index}: t = {self.t:.6g}, step {self.step}>"

    def _data(self, name):
        if name not in self._cache:
            with _open(self._run.path) as f:
                g = f[f"snapshots/{self.index}"]
                self._cache[name] = g[name][()] if name in g else None
        return self._cache[name]

    @property
    def y(self):
        return self._data("y")

    @property
    def x(self):
        x = self._data("x")
        return self._data("y") if x is None else x  # format 1: the coefficients

    @property
    def phi(self):
        return self._data("phi")

    @property
    def velocity(self):
        return self._data("velocity")

    @property
    def triangles(self):
        return self._run._triangles(self.mesh)

    @property
    def interface(self):
        """The phi = 0 curve(s) of the piecewise-linear interpolant of phi on
        the triangles at the positions x: a list of m x 2 arrays (r, z) in R0,
        one per connected piece, sorted by their largest z. An open piece runs
        from its end of larger z to the other (north pole to south pole for a
        vesicle closed by the axis), a closed piece clockwise from its top,
        repeating its first point at the end: the region a piece encloses
        lies on its right. `r, z = piece.T`. Read from the file
        (/snapshots/<k>/interface, written by vesica's
        ves_level_set_curves_eval) when it stores them, else found here by
        marching triangles (files of older versions). Empty, and the area and
        volume NaN, when x or phi hold NaN (a snapshot whose material could
        not be evaluated)."""
        return self._interface()[0]

    @property
    def interface_stored(self):
        """Whether the file stores this snapshot's interface (then .interface
        and the measures are the file's)."""
        return self._stored_interface() is not None

    def _stored_interface(self):
        if "stored" not in self._cache:
            with _open(self._run.path) as f:
                g = f[f"snapshots/{self.index}"]
                if "interface" in g:
                    ig = g["interface"]
                    count = int(ig.attrs.get("pieces", 0))
                    self._cache["stored"] = ([ig[str(i)][()] for i in range(count)],
                                             {k: _text(v) for k, v in ig.attrs.items()})
                else:
                    self._cache["stored"] = None
        return self._cache["stored"]

    def _interface(self):
        if self._curves is None:
            stored = self._stored_interface()
            x, phi = self.x, self.phi
            if not (np.all(np.isfinite(x)) and np.all(np.isfinite(phi))):
                # the material could not be evaluated (docs/manual.md,
                # "The HDF5 file"): no curve, area and volume NaN
                self._curves = [], None
            elif stored is not None:
                self._curves = stored[0], None
            else:
                self._curves = interface_curves(x, phi, self.triangles)
        return self._curves

    def interface_area(self):
        """2 pi int r ds over the phi = 0 segments (R0^2): `vesica info`'s
        interface_area (the file's attribute when it stores the interface)."""
        return self._measure("area", lambda a, b: 2 * math.pi * float(
            np.sum(0.5 * (a[:, 0] + b[:, 0]) * np.hypot(b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]))))

    def interface_volume(self):
        """The volume where phi > 0 (R0^3), pi int r^2 dz along the phi = 0
        segments, each with phi > 0 on its left within its triangle (Green's
        theorem; the axis r = 0 adds nothing): `vesica info`'s
        interface_volume, the same sum the C code (solver/analysis/level_set.c)
        takes over the clipped triangles (the file's attribute when it
        stores the interface)."""
        return self._measure("volume", lambda a, b: math.pi * float(np.sum(
            (b[:, 1] - a[:, 1]) * (a[:, 0] ** 2 + a[:, 0] * b[:, 0] + b[:, 0] ** 2) / 3)))

    def _measure(self, name, over_segments):
        """The stored interface's attribute name (written only for a finite
        state), else over_segments(a, b) of the segments' ends from marching
        triangles: NaN without segments data, 0 for an empty zero set."""
        stored = self._stored_interface()
        if stored is not None:
            return float(stored[1][name])
        seg = self._interface()[1]
        if seg is None:
            return math.nan
        if len(seg) == 0:
            return 0.0
        return over_segments(seg[:, 0], seg[:, 1])


def interface_curves(x, phi, triangles):
    """The phi = 0 line of the piecewise-linear phi on the triangles.

    x: n x 2 positions, phi: n values, triangles: ntri x 3 indices. A vertex
    counts as inside when phi > 0 (as in level_set.c). Returns (curves,
    segments): curves as Snapshot.interface describes; segments an s x 2 x 2
    array of the zero segments, each from the edge where the triangle's
    vertex order leaves phi > 0 to the edge where it enters it (phi > 0 on
    its left when the triangle is counter-clockwise)."""
    x = np.asarray(x, dtype=float)
    phi = np.asarray(phi, dtype=float)
    tri = np.asarray(triangles, dtype=np.int64)
    n = len(phi)
    f = phi[tri]
    pos = f > 0
    npos = pos.sum(axis=1)
    cut = np.nonzero((npos == 1) | (npos == 2))[0]
    if len(cut) == 0:
        return [], np.zeros((0, 2, 2))
    out_key = np.zeros(len(cut), dtype=np.int64)
    in_key = np.zeros(len(cut), dtype=np.int64)
    out_pt = np.zeros((len(cut), 2))
    in_pt = np.zeros((len(cut), 2))
    tc, fc, pc = tri[cut], f[cut], pos[cut]
    for j in range(3):
        j2 = (j + 1) % 3
        va, vb = tc[:, j], tc[:, j2]
        fa, fb = fc[:, j], fc[:, j2]
        cross = pc[:, j] != pc[:, j2]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = fa / (fa - fb)
        a, b = x[va], x[vb]
        q = a + s[:, None] * (b - a)
        # the key of a crossing: its edge, or the vertex when phi is 0 there
        # (the curve passes through it), so neighbours share it
        lo, hi = np.minimum(va, vb), np.maximum(va, vb)
        key = n + lo * n + hi
        neg = np.where(pc[:, j], vb, va)  # the end with phi <= 0
        at_vertex = phi[neg] == 0
        key = np.where(at_vertex, neg, key)
        q = np.where(at_vertex[:, None], x[neg], q)
        leave = cross & pc[:, j]  # phi > 0 at a, not at b
        enter = cross & ~pc[:, j]
        out_key[leave], out_pt[leave] = key[leave], q[leave]
        in_key[enter], in_pt[enter] = key[enter], q[enter]
    segments = np.stack([out_pt, in_pt], axis=1)
    return _orient(_chain(out_key, in_key, out_pt, in_pt)), segments


def _orient(curves):
    """The pieces as vesica stores them (level_set.h): an open piece from its
    end of larger z (at equal z, of smaller r), a closed one clockwise from
    its point of largest z (at equal z, of smallest r); sorted by their
    largest z, descending."""
    out = []
    for c in curves:
        closed = len(c) > 2 and np.array_equal(c[0], c[-1])
        if not closed:
            if c[-1, 1] > c[0, 1] or (c[-1, 1] == c[0, 1] and c[-1, 0] < c[0, 0]):
                c = c[::-1]
        else:
            v = c[:-1]
            top = max(range(len(v)), key=lambda i: (v[i, 1], -v[i, 0]))
            v = np.roll(v, -top, axis=0)
            if np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]) > 0:
                v = np.concatenate([v[:1], v[1:][::-1]])  # clockwise, from the top
            c = np.concatenate([v, v[:1]])
        out.append(np.ascontiguousarray(c))
    return sorted(out, key=lambda c: (-c[:, 1].max(), c[0, 0]))


def _chain(ka, kb, pa, pb):
    """Join segments ka -> kb into connected pieces, each oriented along most
    of its segments."""
    point, adj = {}, {}
    for i in range(len(ka)):
        a, b = int(ka[i]), int(kb[i])
        point.setdefault(a, pa[i])
        point.setdefault(b, pb[i])
        adj.setdefault(a, []).append((b, i, 1))
        adj.setdefault(b, []).append((a, i, -1))
    used = np.zeros(len(ka), dtype=bool)
    curves = []

    def walk(start):
        keys, votes, k = [start], 0, start
        while True:
            nxt = [e for e in adj[k] if not used[e[1]]]
            if not nxt:
                return keys, votes
            k2, i, d = nxt[0]
            used[i] = True
            votes += d
            keys.append(k2)
            k = k2
            if k == start:
                return keys, votes

    ends = [k for k, e in adj.items() if len(e) % 2 == 1]
    for start in ends + list(adj):
        while any(not used[e[1]] for e in adj[start]):
            keys, votes = walk(start)
            if votes < 0:
                keys.reverse()
            curves.append(np.array([point[k] for k in keys]))
    return curves


class Run:
    """A run's file read with h5py (vesica.load)."""

    def __init__(self, path):
        self.path = str(path)
        self._tri = {}
        with _open(self.path) as f:
            if f.attrs.get("program", b"") not in (b"vesica", "vesica"):
                raise ValueError(f"{self.path}: not a vesica output file (no root attribute program = vesica)")
            self.attrs = {k: _text(v) for k, v in f.attrs.items()}
            self.format_version = int(self.attrs.get("format_version", 0))
            self.problem = self.attrs.get("problem")
            self.parameters = (
                {k: _text(v) for k, v in f["parameters"].attrs.items()} if "parameters" in f else {}
            )
            self._runs = self._read_provenance(f)
            self.remeshes = self._read_remeshes(f)
            self.snapshots = self._read_snapshots(f)
            self.series = self._read_series(f)

    def __repr__(self):
        return (f"<vesica.Run {self.path}: {len(self.series)} series rows (t = 0 included), "
                f"{len(self.snapshots)} snapshots, {len(self.remeshes)} remeshings>")

    @property
    def provenance(self):
        """Who and what made the file, a dict: the root attributes program,
        version, backend, source, format_version, setup_seconds, status (None
        where the file has none); the items of the run that created the file
        (/provenance/0: version, commit, compiler, cflags, hdf5, mumps,
        ipopt, nlopt, openblas, openblas_core, host, threads, started,
        command; docs/manual.md, "Output format"); and "runs", the items of
        every run that wrote the file (the first, then each restart), in
        order ([] for a file of an older version)."""
        keys = ["program", "version", "backend", "source", "format_version", "setup_seconds", "status"]
        p = {k: self.attrs.get(k) for k in keys}
        p.update(self._runs[0] if self._runs else {})
        p["runs"] = [dict(r) for r in self._runs]
        return p

    def _read_provenance(self, f):
        if "provenance" not in f:
            return []
        g = f["provenance"]
        count = int(g.attrs.get("count", 0))
        return [{k: _text(v) for k, v in g[str(k)].attrs.items() if k not in ("units", "description")}
                for k in range(count)]

    def _read_remeshes(self, f):
        if "remeshes" not in f:
            return []
        g = f["remeshes"]
        count = int(g.attrs.get("count", 0))
        return [{k: _text(v) for k, v in g[str(k)].attrs.items()} for k in range(count)]

    def _read_snapshots(self, f):
        if "snapshots" not in f:
            return []
        g = f["snapshots"]
        count = int(g.attrs.get("count", 0))
        # the groups are named 0, 1, ..., 10, ... (HDF5 lists them as text:
        # '0', '1', '10', '2'); the count first are complete
        names = sorted((int(k) for k in g.keys() if k.isdigit()))
        names = [k for k in names if k < count]
        if names != list(range(count)):
            raise ValueError(f"{self.path}: /snapshots counts {count} but holds groups {names}")
        snaps = []
        for k in names:
            attrs = {a: _text(v) for a, v in g[str(k)].attrs.items()}
            step = int(attrs["step"])
            mesh = -1
            for j in range(len(self.remeshes) - 1, -1, -1):  # the last remeshing at or before it
                if int(self.remeshes[j]["step"]) <= step:
                    mesh = j
                    break
            snaps.append(Snapshot(self, k, attrs, mesh))
        t = [s.t for s in snaps]
        if any(b < a for a, b in zip(t, t[1:])):
            raise ValueError(f"{self.path}: snapshot times not in order: {t}")
        return snaps

    def _read_series(self, f):
        g = f["series"] if "series" in f else {}
        names = list(g.keys())
        rows = min((g[c].shape[0] for c in names), default=0)
        file_rows = {c: g[c][:rows] for c in names}
        # a run killed between extending "step" and writing it leaves 0 there
        while rows > 0 and "step" in file_rows and int(file_rows["step"][rows - 1]) != rows - 1 \
                and int(file_rows["step"][0]) == 0:
            rows -= 1
            file_rows = {c: v[:rows] for c, v in file_rows.items()}
        known = [c for c in _SERIES_ORDER if c in file_rows]
        order = known + sorted(c for c in file_rows if c not in _SERIES_ORDER) + \
            (["step"] if "step" in file_rows else [])
        if rows > 0 and "step" in file_rows and int(file_rows["step"][0]) == 0:
            # the file stores the initial state's row (step 0, t = 0)
            return Series({c: file_rows[c].astype(float) for c in order},
                          {c: file_rows[c] for c in order})
        snap0 = self.snapshots[0].attrs if self.snapshots else {}
        at0 = {
            "t": 0.0, "step": 0, "E": self.attrs.get("E0"), "A": self.attrs.get("A0"),
            "V": self.attrs.get("V0"), "V_target": self.attrs.get("V0"),
            "c0": snap0.get("c0"), "lambda_A": snap0.get("lambda_A"),
            "lambda_V": snap0.get("lambda_V"), "wall_seconds": 0.0, "reconnections": 0,
        }
        cols = {}
        for c in names:
            v0 = at0.get(c)
            first = np.array([np.nan if v0 is None else float(v0)])
            cols[c] = np.concatenate([first, file_rows[c].astype(float)])
        # the layout's order (docs/manual.md, "The series"), other columns after it, step last
        return Series({c: cols[c] for c in order}, {c: file_rows[c] for c in order})

    def _triangles(self, mesh):
        if mesh not in self._tri:
            with _open(self.path) as f:
                d = "mesh/triangles" if mesh < 0 else f"remeshes/{mesh}/triangles"
                self._tri[mesh] = f[d][()]
        return self._tri[mesh]

    def snapshot_at(self, t):
        """The snapshot nearest to time t."""
        return min(self.snapshots, key=lambda s: abs(s.t - t))


def load(path):
    """Read the vesica output file at path (FILE.h5): a Run with series,
    snapshots (in time order), remeshes, problem, parameters, attrs, provenance."""
    return Run(path)


def load_study(folder):
    """A study's table DIR/study.csv (docs/manual.md, "Running a study") as
    column name -> numpy array: numbers as floats (an empty field NaN),
    text columns (cell, status, reason, backend ...) as str arrays."""
    import csv
    import os

    path = os.path.join(str(folder), "study.csv")
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise ValueError(f"{path}: empty (no header line)")
    head, body = rows[0], rows[1:]
    table = {}
    for i, c in enumerate(head):
        vals = [r[i] if i < len(r) else "" for r in body]
        try:
            table[c] = np.array([float(v) if v != "" else np.nan for v in vals])
        except ValueError:
            table[c] = np.array(vals, dtype=str)
    return table
