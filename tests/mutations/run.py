"""Mutation check: apply each deliberate bug of mutations.py, one at a time, to a temporary copy
of the repository, run the tests named for it (or the whole default suite), and report which
tests caught it. Every mutation must be caught; the exit code is 1 if one is not.

Not part of the default suite (pytest collects test_*.py only). Run from the repository:

    ./dev python tests/mutations/run.py                  # every mutation, its own test files
    ./dev python tests/mutations/run.py --all-tests      # every mutation, the whole default suite
    ./dev python tests/mutations/run.py --only camera_flipped_in_y spot_smoothstep_to_linear

The copy is `git archive <rev>` (default HEAD: the working tree is never touched, other work
may be under way in it) with the working tree's tests/ laid over it (so new tests can be tried
before they are committed; --no-overlay turns that off), or with --worktree every tracked and
untracked, not ignored file as it is now. Tests run with the repository's .venv and
PYTHONDONTWRITEBYTECODE=1 (a restored file is never shadowed by a stale .pyc). A baseline run
without any mutation comes first: a test that already fails there catches nothing.
"""
from __future__ import annotations

import argparse
import io
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path.insert(0, str(HERE))
from mutations import MUTATIONS  # noqa: E402

FAILED = re.compile(r"^(?:FAILED|ERROR) (\S+?)(?: - .*)?$", re.MULTILINE)
SUMMARY = re.compile(r"^=+ (.*(?:passed|failed|error).*) in [\d.]+s", re.MULTILINE)


def export(rev: str, worktree: bool, overlay: bool, dest: pathlib.Path) -> None:
    if worktree:
        files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=ROOT, check=True,
                               capture_output=True).stdout.decode().split("\0")
        for f in filter(None, files):
            src = ROOT / f
            if src.is_file():
                (dest / f).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(src, dest / f)
        return
    data = subprocess.run(["git", "archive", rev], cwd=ROOT, check=True, capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(dest, filter="data")
    if overlay:
        for src in (ROOT / "tests").rglob("*"):
            if src.is_file() and "__pycache__" not in src.parts:
                target = dest / src.relative_to(ROOT)
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(src, target)


def run_tests(copy: pathlib.Path, tests: list[str], timeout: float) -> tuple[set[str], str, float]:
    """(failing node ids, pytest's summary line, seconds) of one pytest run in the copy."""
    env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
    env.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ember_mut_bur_"))
    t0 = time.perf_counter()
    try:
        proc = subprocess.run([str(ROOT / ".venv" / "bin" / "python"), "-m", "pytest", "-q", "-rfE", "-p",
                               "no:randomly", *tests], cwd=copy, env=env, capture_output=True, text=True,
                              timeout=timeout)
        out = proc.stdout + proc.stderr
    except subprocess.TimeoutExpired as e:
        out = (e.stdout or b"").decode(errors="replace") if isinstance(e.stdout, bytes) else (e.stdout or "")
        out += "\nTIMEOUT"
    failed = set(FAILED.findall(out))
    m = SUMMARY.findall(out)
    summary = m[-1] if m else ("timeout" if out.endswith("TIMEOUT") else out.strip().splitlines()[-1:] or ["?"])[0]
    if not failed and "TIMEOUT" in out[-10:]:
        failed = {"<timeout>"}
    return failed, summary, time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rev", default="HEAD", help="commit to copy (default HEAD)")
    ap.add_argument("--worktree", action="store_true", help="copy the working tree as it is instead of a commit")
    ap.add_argument("--no-overlay", action="store_true", help="do not lay the working tree's tests/ over the commit")
    ap.add_argument("--all-tests", action="store_true", help="run the whole default suite for every mutation")
    ap.add_argument("--only", nargs="*", help="names of the mutations to apply")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per pytest run")
    ap.add_argument("--keep", action="store_true", help="keep the temporary copy")
    args = ap.parse_args(argv)

    chosen = [m for m in MUTATIONS if not args.only or m["name"] in args.only]
    unknown = set(args.only or ()) - {m["name"] for m in MUTATIONS}
    if unknown:
        print(f"unknown mutation(s): {', '.join(sorted(unknown))}", file=sys.stderr)
        return 2
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="ember_mutations_"))
    copy = tmp / "repo"
    copy.mkdir()
    export(args.rev, args.worktree, not args.no_overlay, copy)
    source = "working tree" if args.worktree else f"{args.rev}" + ("" if args.no_overlay else " + working-tree tests/")
    print(f"copy of {source} in {copy}", flush=True)

    def tests_for(m):
        return [] if args.all_tests else list(m["tests"])

    # Baseline: the union of the test selections, unmutated.
    union = [] if args.all_tests else sorted({t for m in chosen for t in m["tests"]})
    base_failed, base_summary, secs = run_tests(copy, union, args.timeout)
    print(f"baseline ({' '.join(union) or 'default suite'}): {base_summary} [{secs:.0f} s]", flush=True)
    for f in sorted(base_failed):
        print(f"  baseline failure (ignored below): {f}")

    rows, missed = [], []
    for m in chosen:
        path = copy / m["file"]
        original = path.read_text()
        count = original.count(m["old"])
        if count != 1:
            rows.append((m["name"], "ANCHOR", f"old text found {count} times in {m['file']}", ""))
            missed.append(m["name"])
            print(f"{m['name']}: anchor found {count} times in {m['file']}", flush=True)
            continue
        path.write_text(original.replace(m["old"], m["new"]))
        try:
            failed, summary, secs = run_tests(copy, tests_for(m), args.timeout)
        finally:
            path.write_text(original)
        caught_by = sorted(failed - base_failed)
        status = "caught" if caught_by else "MISSED"
        if not caught_by:
            missed.append(m["name"])
        rows.append((m["name"], status, summary, caught_by))
        print(f"{m['name']}: {status} ({summary}) [{secs:.0f} s]", flush=True)
        for t in caught_by:
            print(f"    {t}")

    print("\n## Mutation report\n")
    print(f"Source: {source}; tests: {'whole default suite' if args.all_tests else 'per-mutation selection'}\n")
    print("| mutation | what it breaks | result | caught by |")
    print("|---|---|---|---|")
    notes = {m["name"]: m["note"] for m in MUTATIONS}
    for name, status, summary, caught_by in rows:
        if isinstance(caught_by, list) and caught_by:
            shown = ", ".join(t.split("/")[-1] for t in caught_by[:4])
            more = f" (+{len(caught_by) - 4} more)" if len(caught_by) > 4 else ""
            by = f"{len(caught_by)} tests: {shown}{more}"
        else:
            by = summary
        print(f"| {name} | {notes[name]} | {status} | {by} |")
    print(f"\n{len(rows) - len(missed)} of {len(rows)} mutations caught" + (f"; missed: {', '.join(missed)}" if missed else ""))
    if args.keep:
        print(f"copy kept in {copy}")
    else:
        shutil.rmtree(tmp, ignore_errors=True)
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
