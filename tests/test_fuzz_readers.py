"""A bounded fault campaign in the suite (the full one is ``benchmarks/fuzz_readers.py``): a few hundred
mutated copies of small shared logs and .mat files (and of CSV/NPZ/.mat flights derived from flight A), each
read in a worker process; no crash, nothing but the library's error, no NaN/Inf loaded, no silent truncation."""

import pytest

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import fuzz_readers  # noqa: E402

MUTATIONS = 400


@pytest.fixture(scope="module")
def seeds(shared_data, tmp_path_factory):
    return fuzz_readers.seeds(shared_data, tmp_path_factory.mktemp("seeds"))


def test_mutated_files_fail_cleanly_or_load_finite(seeds, tmp_path):
    result = fuzz_readers.campaign(seeds, MUTATIONS, seed=17, work=tmp_path)
    assert result["seeds"] == {s.name: ("error" if s.name == "Record.mat" else "loaded") for s in seeds}
    _assert_clean(result, MUTATIONS)


def test_element_tags_of_uncompressed_mat_files(seeds, tmp_path):
    """The mutation that crashed scipy's reader: a changed type byte in an element tag (about 1 in 30 such
    copies of these files kills a bare ``scipy.io.loadmat``)."""
    plain = [s for s in seeds if s.tags]
    assert {s.name for s in plain} == {"plain400.mat", "iddata400.mat"}
    _assert_clean(fuzz_readers.campaign(plain, 150, seed=3, work=tmp_path, kinds=("tag",)), 150)


def _assert_clean(result, mutations):
    assert sum(result["tally"].values()) == mutations
    notable = [{k: c.get(k) for k in ("outcome", "seed", "kind", "type", "message")} for c in result["cases"]
               if c["outcome"] != "changed" or c["silent"]]
    assert not notable
    assert result["crashes"] == result["foreign"] == result["non_finite_loaded"] == result["silent_truncations"] == 0
