"""The test suite's time against a reference commit's, measured one after the other on the same machine.

A suite's seconds say as much about the machine as about the code: the same commit's suite has run 2.7 times
longer on one day than on another here. This script clones the repository at a reference commit and at the commit
under test, runs README's test command in each clean clone (a fresh venv, ``JAXHELI_REQUIRE_DATA=1``, the browser
test required where Chromium is installed), and writes both times and their ratio as JSON, so a time limit set
on one machine reads on another as a ratio to the reference::

    python benchmarks/suite_time.py --reference 7943b6d --reference-ci-s 656 --out /tmp/suite-time

``--reference-ci-s``: the reference's suite time in CI when the limit was set; the JSON then gives the tested
commit's estimate on that machine (the ratio times it), labelled an estimate.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
INSTALL = 'python3 -m venv .venv && . .venv/bin/activate && pip install -q -e ".[test]"'
TESTS = ". .venv/bin/activate && python -m pytest -q -n 2 --dist loadfile"
"""README's test command, split where the install ends so that the suite is timed alone."""
_SUMMARY = re.compile(r"^=*\s*(?P<counts>.*?) in (?P<seconds>[0-9.]+)s", re.M)


def _commit(ref: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), "rev-parse", ref], capture_output=True, text=True,
                          check=True).stdout.strip()


def _summary(text: str) -> tuple[dict[str, int], float]:
    """pytest's closing line (``1129 passed, 2 failed in 1472.56s``) as ``({"passed": 1129, "failed": 2}, 1472.56)``."""
    found = _SUMMARY.findall(text)
    if not found:
        raise RuntimeError(f"no pytest summary line in the output's end:\n{text[-2000:]}")
    counts, seconds = found[-1]
    return {kind: int(n) for n, kind in re.findall(r"(\d+) (\w+)", counts)}, float(seconds)


def run_suite(ref: str, work: Path, env: dict[str, str]) -> dict:
    """README's test command in a clean clone of ``ref`` under ``work``: counts, pytest's own seconds, wall seconds."""
    commit = _commit(ref)
    clone = work / commit[:12]
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    subprocess.run(["git", "-C", str(clone), "checkout", "-q", commit], check=True)
    subprocess.run(INSTALL, shell=True, cwd=clone, env=env, check=True, executable="/bin/bash")
    start = time.perf_counter()
    done = subprocess.run(TESTS, shell=True, cwd=clone, env=env, capture_output=True, text=True,
                          executable="/bin/bash")
    wall = time.perf_counter() - start
    (work / f"{commit[:12]}.log").write_text(done.stdout + done.stderr)
    counts, seconds = _summary(done.stdout)
    return {"commit": commit, "returncode": done.returncode, "counts": counts, "pytest_s": seconds,
            "wall_s": round(wall, 1)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--reference", default="7943b6d", help="commit whose suite sets the scale (default %(default)s)")
    parser.add_argument("--commit", default="HEAD", help="commit under test (default %(default)s)")
    parser.add_argument("--reference-ci-s", type=float, help="the reference's suite time in CI when the limit was set")
    parser.add_argument("--out", type=Path, required=True, help="folder for suite_time.json and the two logs")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "JAXHELI_REQUIRE_DATA": "1", "PIP_DISABLE_PIP_VERSION_CHECK": "1"}
    env.setdefault("JAXHELI_DATA", str(ROOT.parent / "shared" / "data"))
    if shutil.which("chromium"):
        env["JAXHELI_REQUIRE_BROWSER"] = "1"
    work = Path(tempfile.mkdtemp(prefix="jaxheli-suite-time-"))
    try:
        runs = [run_suite(ref, work, env) for ref in (args.reference, args.commit)]
        for run in runs:
            shutil.copy(work / f"{run['commit'][:12]}.log", args.out)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    reference, tested = runs
    ratio = tested["pytest_s"] / reference["pytest_s"]
    result = {"reference": reference, "tested": tested, "ratio": round(ratio, 3), "order": "reference first",
              "reference_ci_s": args.reference_ci_s,
              "estimated_ci_s": None if args.reference_ci_s is None else round(ratio * args.reference_ci_s, 1)}
    (args.out / "suite_time.json").write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0 if all(r["returncode"] == 0 for r in runs) else 1


if __name__ == "__main__":
    raise SystemExit(main())
