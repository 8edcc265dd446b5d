#!/usr/bin/env python3
"""scripts/perf_compare.sh on bad input (issue 31): a ref that does not exist and a ref that
does not build are errors naming the ref and the failing step; bad arguments are refused; the
working tree is never modified.

Usage: perf_compare_test.py REPO_ROOT
"""
import subprocess
import sys
import tempfile
from pathlib import Path


def run(cmd, cwd):
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=600)


def expect(cond, what, r=None):
    if not cond:
        detail = f"\nrc {r.returncode}\nstdout:\n{r.stdout}\nstderr:\n{r.stderr}" if r else ""
        print(f"FAIL: {what}{detail}")
        sys.exit(1)
    print(f"ok: {what}")


def main():
    root = Path(sys.argv[1]).resolve()
    script = root / "scripts" / "perf_compare.sh"
    git = run(["git", "rev-parse", "--is-inside-work-tree"], root)
    if git.returncode != 0:
        print("SKIP: not a git work tree")
        return 0
    status_before = run(["git", "status", "--porcelain"], root).stdout
    with tempfile.TemporaryDirectory() as tmp:
        r = run(["bash", str(script), "no-such-ref-31", "--out", tmp], root)
        expect(r.returncode == 3 and "no-such-ref-31" in r.stderr and "does not exist" in r.stderr,
               "a ref that does not exist: exit 3 naming it", r)
        r = run(["bash", str(script), "HEAD", "--reps", "x", "--out", tmp], root)
        expect(r.returncode == 2 and "'x' is not a positive integer" in r.stderr,
               "a bad --reps: exit 2 naming the value", r)
        r = run(["bash", str(script)], root)
        expect(r.returncode == 2 and "usage:" in r.stderr, "no ref: exit 2 with the usage", r)
        # The repository's first commit has no ingest benchmark: its build fails.
        first = run(["git", "rev-list", "--max-parents=0", "HEAD"], root).stdout.split()
        shallow = run(["git", "rev-parse", "--is-shallow-repository"], root).stdout.strip()
        if first and shallow != "true":
            ref = first[-1][:12]
            r = run(["bash", str(script), ref, "--out", tmp, "--build-only"], root)
            expect(r.returncode == 4 and ref in r.stderr and
                   ("build failed" in r.stderr or "configure failed" in r.stderr),
                   "a ref that does not build: exit 4 naming the ref and the step", r)
        else:
            print("skip: a shallow clone has no first commit to build")
    status_after = run(["git", "status", "--porcelain"], root).stdout
    expect(status_after == status_before, "the working tree is not modified")
    return 0


if __name__ == "__main__":
    sys.exit(main())
