#!/usr/bin/python3
"""The --series text of `vesica run` as a script reads it (docs/manual.md, "The series"): one
short adaptive run of build/vesica (the TINY settings of tests/cli_test_impl.h, 6 steps) with
--series. numpy.genfromtxt(names=True) reads every column by name with no NaN; the first row is
the initial state at t = 0 (E0, A0, V0 of the file); the names, their order and every row's
values are those of `vesica info FILE.h5 --series 0`; the manual's table of the columns names
the same columns in that order, with the units the file's datasets carry.

Run with Debian's python3 (numpy, h5py): /usr/bin/python3 tests/test_series_tsv.py; prints
cmocka's summary lines for tests/run.sh; exit 1 when a check fails. VESICA names the program
(default build/vesica, else build-san/vesica)."""
import os
import re
import subprocess
import sys
import tempfile

import h5py
import numpy as np

import py_test_impl  # tests/, beside this file
from py_test_impl import ROOT, VESICA

STEPS = 6
TMP = tempfile.mkdtemp(prefix="vesica_series_tsv_")
OUT = os.path.join(TMP, "s.h5")
TSV = os.path.join(TMP, "s.tsv")


def setup():
    # adaptive steps, stopped by --max-steps
    py_test_impl.tiny_run("[time]\nt_end = 1\n", OUT, "--series", TSV, "--max-steps", str(STEPS))


def info_series():
    """vesica info --series 0: the names (after '# ') and the rows as lists of fields."""
    p = subprocess.run([VESICA, "info", OUT, "--series", "0"], capture_output=True, text=True)
    assert p.returncode == 0, f"vesica info --series 0: exit {p.returncode}: {p.stderr}"
    lines = p.stdout.splitlines()
    assert lines[0].startswith("# "), lines[0]
    return lines[0][2:].split("\t"), [line.split("\t") for line in lines[1:]]


def tsv_lines():
    with open(TSV) as f:
        return f.read().splitlines()


def test_genfromtxt_reads_every_column():
    a = np.genfromtxt(TSV, names=True, delimiter="\t")
    names, _ = info_series()
    assert list(a.dtype.names) == names, (a.dtype.names, names)
    assert a.shape == (STEPS + 1,), a.shape  # the t = 0 row and one a step
    for n in a.dtype.names:
        assert np.all(np.isfinite(a[n])), (n, a[n])
    # the header is one line of names: no comment mark, nothing before it
    first = tsv_lines()[0]
    assert not first.startswith("#") and first.split("\t") == names, first


def test_first_row_is_t0():
    a = np.genfromtxt(TSV, names=True, delimiter="\t")
    assert a["t"][0] == 0 and a["step"][0] == 0 and a["dt"][0] == 0, a[0]
    assert list(a["step"]) == list(range(STEPS + 1)), a["step"]
    assert np.all(np.diff(a["t"]) > 0), a["t"]
    with h5py.File(OUT, "r") as f:
        E0, A0, V0 = (float(f.attrs[k]) for k in ("E0", "A0", "V0"))
    # the text holds 12 significant digits (%.12g): 1e-11 relative covers its rounding
    for name, v in (("E", E0), ("A", A0), ("V", V0), ("V_target", V0)):
        assert abs(a[name][0] / v - 1) <= 1e-11, (name, a[name][0], v)


def test_rows_equal_info_series():
    names, rows = info_series()
    lines = tsv_lines()
    assert lines[0].split("\t") == names
    text = {int(line.split("\t")[0]): line.split("\t") for line in lines[1:]}
    steps = [int(r[0]) for r in rows]
    # the file's rows: every accepted step (and its t = 0 row when it keeps one)
    assert set(range(1, STEPS + 1)) <= set(steps) <= set(range(STEPS + 1)), steps
    for r in rows:  # the same text, field by field: both print %.12g of the same values
        assert text[int(r[0])] == r, (r, text[int(r[0])])


def test_manual_table_names_and_units():
    with open(os.path.join(ROOT, "docs", "manual.md")) as f:
        doc = f.read()
    sec = doc[doc.index("### The series: one row per accepted step"):]
    sec = sec[:sec.index("\n### ")]
    table = re.findall(r"^\| `(\w+)` \| ([^|]+) \|", sec, re.M)
    names, _ = info_series()
    assert [n for n, _ in table] == names, ([n for n, _ in table], names)
    with h5py.File(OUT, "r") as f:
        for n, units in table:
            u = f["series"][n].attrs["units"]
            u = u.decode() if isinstance(u, bytes) else str(u)
            assert units.strip() == u, (n, units, u)


TESTS = [test_genfromtxt_reads_every_column, test_first_row_is_t0, test_rows_equal_info_series,
         test_manual_table_names_and_units]



sys.exit(py_test_impl.run(TESTS, setup, TMP))
