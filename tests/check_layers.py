#!/usr/bin/env python3
"""The include graph of the library and the program, checked against the layers.

Each file under solver/<folder>/ belongs to that folder; a public header
include/ves/X.h belongs to the folder that holds X.c or X.cpp. From the
#include "..." lines this builds the graph between folders and fails (exit 1,
one line per offence) when
  - a library folder includes a header of the program (solver/app),
  - a file includes a private header (*_impl.h) of another folder (those of
    solver/core, the library's clock, memory and OpenMP helpers, serve every
    folder),
  - a public header includes a program header,
  - a folder includes one above it in the layer order (docs/design.md,
    "Layers and interfaces"), which also rules out any circle.
With --dot it prints the folder graph in Graphviz form instead.
"""
import os
import re
import sys

LAYERS = ["core", "linalg", "discret", "model", "step", "backends", "time", "analysis", "app"]
RANK = {name: i for i, name in enumerate(LAYERS)}
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def sources(root):
    for folder in LAYERS:
        d = os.path.join(root, "solver", folder)
        for name in sorted(os.listdir(d)) if os.path.isdir(d) else []:
            if name.endswith((".c", ".h", ".cpp")):
                yield folder, os.path.join(d, name)
    d = os.path.join(root, "include", "ves")
    for name in sorted(os.listdir(d)):
        if name.endswith(".h"):
            yield None, os.path.join(d, name)


def owner_of_public(root):
    """ves/X.h -> the folder holding X.c or X.cpp."""
    owner = {}
    for folder in LAYERS:
        d = os.path.join(root, "solver", folder)
        for name in os.listdir(d) if os.path.isdir(d) else []:
            stem, ext = os.path.splitext(name)
            if ext in (".c", ".cpp"):
                owner.setdefault("ves/%s.h" % stem, folder)
    return owner


def offences(root):
    """The offence lines and the folder arrows of the tree at root."""
    owner = owner_of_public(root)
    errors, edges = [], set()
    for folder, path in sources(root):
        rel = os.path.relpath(path, root)
        if folder is None:  # a public header: it belongs to its module's folder
            folder = owner.get("ves/" + os.path.basename(path))
            if folder is None:
                errors.append("%s: a public header with no source file in solver/<layer>/" % rel)
                continue
        for inc in INCLUDE.findall(open(path, encoding="utf-8").read()):
            if inc.startswith("ves/"):
                target = owner.get(inc)
                if target is None:
                    errors.append("%s: includes %s, which no library folder implements" % (rel, inc))
                    continue
            elif "/" in inc:
                target = inc.split("/", 1)[0]
                if target not in RANK:
                    continue
                if inc.endswith("_impl.h") and target not in (folder, "core"):
                    errors.append("%s: includes %s, a private header of solver/%s" % (rel, inc, target))
            else:
                continue  # a header beside the file (tests, benches)
            if target != folder:
                edges.add((folder, target))
            if target == "app" and folder != "app":
                errors.append("%s: the library includes the program's header %s" % (rel, inc))
            elif RANK[target] > RANK[folder]:
                errors.append("%s: includes %s of solver/%s, a layer above solver/%s" % (rel, inc, target, folder))
    return errors, edges


def self_test():
    """The check finds each kind of offence in a small synthetic tree."""
    import tempfile
    cases = {
        "solver/model/m.c": ('#include "app/config.h"\n', "program's header"),
        "solver/step/s.c": ('#include "model/model_impl.h"\n', "private header"),
        "solver/linalg/l.c": ('#include "ves/m.h"\n', "a layer above"),
    }
    for path, (line, want) in cases.items():
        with tempfile.TemporaryDirectory() as root:
            for d in ("include/ves", "solver/core", "solver/model", "solver/app"):
                os.makedirs(os.path.join(root, d), exist_ok=True)
            for f, text in (("solver/model/m.c", ""), ("solver/model/model_impl.h", ""),
                            ("solver/app/config.h", ""), ("include/ves/m.h", "")):
                open(os.path.join(root, f), "w").write(text)
            os.makedirs(os.path.dirname(os.path.join(root, path)), exist_ok=True)
            open(os.path.join(root, path), "w").write(line)
            errors, _ = offences(root)
            if not any(want in e for e in errors):
                print("check-layers: self-test: %s with %s not flagged" % (path, line.strip()))
                return 1
    return 0


def main():
    if self_test():
        return 1
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    errors, edges = offences(root)
    if "--dot" in sys.argv:
        print("digraph vesica {")
        for a, b in sorted(edges, key=lambda e: (RANK[e[0]], RANK[e[1]])):
            print('  "%s" -> "%s";' % (a, b))
        print("}")
        return 0
    for e in errors:
        print("check-layers: " + e)
    if errors:
        print("check-layers: %d offence(s); the layers are %s (lowest first)" % (len(errors), " < ".join(LAYERS)))
        return 1
    print("check-layers: ok (%d folder arrows, all downward)" % len(edges))
    return 0


if __name__ == "__main__":
    sys.exit(main())
