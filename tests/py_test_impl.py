"""The runner shared by the Python test programs (tests/test_*.py): runs
setup() once, then each test, printing cmocka's summary lines so that
tests/run.sh counts them like a C test program's; a failing setup fails
every test. Not a test program itself (its name does not start with
test_)."""
import shutil
import sys
import traceback


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
