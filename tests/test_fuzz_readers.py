"""A bounded fault campaign in the suite (the full one is ``benchmarks/fuzz_readers.py``): a few hundred
mutated copies of small shared logs and .mat files (and of CSV/NPZ/.mat flights derived from flight A), each
read in a worker process; no crash, nothing but the library's error, no NaN/Inf loaded, no silent truncation."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import fuzz_readers  # noqa: E402

MUTATIONS = 400


def test_mutated_files_fail_cleanly_or_load_finite(shared_data, tmp_path):
    seeds = fuzz_readers.seeds(shared_data, tmp_path)
    result = fuzz_readers.campaign(seeds, MUTATIONS, seed=17, work=tmp_path)
    assert result["seeds"] == {s.name: ("error" if s.name == "Record.mat" else "loaded") for s in seeds}
    assert sum(result["tally"].values()) == MUTATIONS
    notable = [{k: c.get(k) for k in ("outcome", "seed", "kind", "type", "message")} for c in result["cases"]
               if c["outcome"] != "changed" or c["silent"]]
    assert not notable
    assert result["crashes"] == result["foreign"] == result["non_finite_loaded"] == result["silent_truncations"] == 0
