"""README's two set-up commands exist, CI runs exactly the test command, and the blind example is not refused."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _commands():
    return re.findall(r"```bash\n(.+?)\n```", (ROOT / "README.md").read_text())


def test_readme_starts_with_main_job_and_test_commands():
    cmds = _commands()
    assert len(cmds) >= 2
    assert "pip install" in cmds[0] and "jaxheli " in cmds[0]
    assert "pip install" in cmds[1] and "pytest" in cmds[1]


def test_ci_runs_exactly_the_readme_test_command():
    ci_lines = (ROOT / ".ci" / "run").read_text().splitlines()
    assert _commands()[1] in ci_lines
    assert any(line.startswith("export JAXHELI_REQUIRE_DATA=1") for line in ci_lines)


def test_the_blind_example_flies_seeds_the_committed_ledger_allows():
    """README's and the blind guide's ``jaxheli blind`` example draws its seeds from the committed seed ledger without a
    refusal (a spent seed is refused before any trial flies): parsed by the command line, each kind's seeds drawn
    as the run draws them."""
    from jaxheli.benchmark.blind import TRUTHS_SIM
    from jaxheli.cli import build_parser
    from jaxheli.gap.thresholds import THRESHOLDS

    examples = {m for doc in ("README.md", "docs/guide/blind.md")
                for m in re.findall(r"jaxheli (blind --[^`\n]+)", (ROOT / doc).read_text()) if "--resume" not in m}
    assert len(examples) == 1, examples
    args = build_parser().parse_args(examples.pop().split())
    control = 2 * args.seeds if args.control_seeds is None else args.control_seeds
    for kind in args.kinds or TRUTHS_SIM[args.truth]:
        drawn = THRESHOLDS.protocol.seeds(args.split, control if kind == "none" else args.seeds, args.skip_seeds,
                                          refly=args.refly_design)
        assert len(drawn) == (control if kind == "none" else args.seeds)
