"""What the Python test programs (tests/test_*.py) share: the program
under test (VESICA), the small problem they run it on (TINY, the settings
of tests/cli_test_impl.h), a run of it that must succeed (tiny_run), and
the runner: setup() once, then each test, printing cmocka's summary lines
so that tests/run.sh counts them like a C test program's; a failing setup
fails every test. Not a test program itself (its name does not start with
test_)."""
import os
import shutil
import subprocess
import sys
import traceback

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VESICA = os.environ.get("VESICA", os.path.join(ROOT, "build", "vesica"))
if "VESICA" not in os.environ and not os.path.exists(VESICA):  # a SAN=1 build alone
    VESICA = os.path.join(ROOT, "build-san", "vesica")
TINY = ["geometry.epsilon=0.2", "geometry.box_r=2", "geometry.box_z=2", "geometry.band=2",
        "geometry.h_band=0.7", "geometry.h_far=0.3", "shape.mode=2", "shape.delta=0.15",
        "time.dt_initial=5e-3", "time.dE_target=0.05"]


def tiny_run(ini_text, out, *args):
    """vesica run of the problem text ini_text (written beside out) with the
    TINY settings, its output out, and args; raises when it fails."""
    ini = os.path.splitext(out)[0] + ".ini"
    with open(ini, "w") as f:
        f.write(ini_text)
    cmd = [VESICA, "run", ini, "--out", out, "--quiet", *args]
    for s in TINY:
        cmd += ["--set", s]
    p = subprocess.run(cmd, capture_output=True, text=True,
                       env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))
    if p.returncode != 0:
        raise AssertionError(f"{' '.join(cmd)}: exit {p.returncode}: {p.stderr}")


def run(tests, setup, tmp):
    """Runs tests after setup(), removes the folder tmp, returns the exit code."""
    failed = []
    print(f"[==========] Running {len(tests)} test(s).")
    try:
        setup()
    except Exception:
        traceback.print_exc(file=sys.stdout)
        failed = [t.__name__ for t in tests]
    for t in tests if not failed else []:
        print(f"[ RUN      ] {t.__name__}")
        sys.stdout.flush()
        try:
            t()
            print(f"[       OK ] {t.__name__}")
        except Exception:
            traceback.print_exc(file=sys.stdout)
            print(f"[  ERROR   ] --- {t.__name__}")
            failed.append(t.__name__)
    shutil.rmtree(tmp, ignore_errors=True)
    print(f"[==========] {len(tests)} test(s) run.")
    print(f"[  PASSED  ] {len(tests) - len(failed)} test(s).")
    if failed:
        print(f"[  FAILED  ] {len(failed)} test(s), listed below:")
        for name in failed:
            print(f"[  FAILED  ] {name}")
    return 1 if failed else 0
