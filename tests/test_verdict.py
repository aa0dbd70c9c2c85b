"""The verdict as a record: what each combination of ranking, base re-fit, structure and re-check finds, the
command line's words for it (the same text the library returned before the record), and no text under
``jaxheli/gap/`` that names a command-line option."""

import ast
import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

from jaxheli.benchmark.blind import regrade, regraded_top
from jaxheli.cli.diagnosis_text import verdict_line
from jaxheli.bounds import Bounds
from jaxheli.gap.candidate_records import Refit, Structure
from jaxheli.gap.fit_effect import EffectFit
from jaxheli.gap.significance import HeldOut, shrink_entries
from jaxheli.gap.verdict import Verdict, find, named, named_entry, sentence
from jaxheli.model import TABLE2
from jaxheli.synth.piloted import DEFAULT_OUTPUTS

OUT = DEFAULT_OUTPUTS
GAP = Path(__file__).resolve().parents[1] / "jaxheli" / "gap"


def _entries(shrinks=(0.6, 0.62, 0.97)):
    """Ranking entries of a delay, a lag and a saturation behind a reference row (window energies ``shrinks`` of
    the reference's), all three significant."""
    k = 2 * len(OUT)
    z = np.zeros((4, k))
    z[1, :4], z[2, :4], z[3, :4] = [0.08, 0.0, 0.0, 0.0], [0.05, 0.0, 0.0, 0.0], [0.01, 0.0, 0.0, 0.0]
    fit = EffectFit(z=z, stderr=np.full((4, k), 0.005), theta=np.tile(TABLE2, (4, 1)),
                    rss=np.array([1.0, 0.6, 0.62, 0.99]), n_eff=np.full(4, 100.0), k_active=np.array([0, 4, 4, 4]), steps=np.full(4, 5),
                    converged=np.full(4, True))
    segs = np.ones((4, 40)) * np.r_[1.0, shrinks][:, None]
    segs *= 1.0 + 0.02 * np.cos(np.arange(40)[None, :] * np.arange(1, 5)[:, None])  # windows differ
    gaps = np.sum(segs, axis=1, keepdims=True) * np.ones(len(OUT)) / 40
    return shrink_entries(["input_delay", "actuator_lag", "control_saturation"], OUT, fit, HeldOut(gaps, segs), 3.0)


def _refit(under_fitted=True, settled=True):
    return Refit(shrink_pct=12.0, shrink_se_pct=2.5, gap_base=0.4, gap=0.35, gap_by_channel=dict.fromkeys(OUT, 0.35),
                 under_fitted=under_fitted, converged=False, progress_pct=3.25, settled=settled, steps=60,
                 theta=np.asarray(TABLE2), nuisance={})


def _structure(shrink, significant=True):
    return Structure(shrink, 5.0, significant, 0.2, 0.2 * (1 - shrink / 100), dict.fromkeys(OUT, 0.1), {"Nw": 2.5},
                     {"Xu": -3.0}, {"Xu": -1.0}, np.zeros(40), {})


def _cases():
    """name -> (ranking, refit, structure, recheck)."""
    ranked = _entries()
    clean = [dataclasses.replace(e, significant=False, tied_with=()) for e in ranked]
    tied = [dataclasses.replace(ranked[0], tied_with=("actuator_lag",)),
            dataclasses.replace(ranked[1], significant=True, tied_with=("input_delay",)), ranked[2]]
    recheck = (dataclasses.replace(ranked[0], shrink_pct=21.5, shrink_se_pct=3.0),)
    return {
        "nothing": (clean, None, None, ()),
        "effect_tied": (tied, None, None, ()),
        "effect_settled_refit": (ranked, _refit(under_fitted=False), None, ()),
        "under_fitted_then_effect": (ranked, _refit(), None, ()),
        "unsettled": ([dataclasses.replace(e, significant=False, tied_with=()) for e in ranked],
                      _refit(settled=False), None, ()),
        "unsettled_not_under": (clean, _refit(under_fitted=False, settled=False), None, ()),
        "structure_then_effect": (ranked, _refit(), _structure(45.0), recheck),
        "effect_beyond_structure": (ranked, None, _structure(30.0), ()),
        "structure_only": (clean, _refit(under_fitted=False), _structure(45.0), ()),
        "idle_structure": (ranked, None, _structure(60.0, significant=False), ()),
    }


GOLDEN = {
    'nothing': (
        'no significant effect'),
    'effect_tied': (
        'input_delay (lat input delay delay 80 +- 5 ms), tied with actuator_lag: gap shrinks 40.0 % on '
        'the validation flight'),
    'effect_settled_refit': (
        'input_delay (lat input delay delay 80 +- 5 ms): gap shrinks 40.0 % on the validation flight'),
    'under_fitted_then_effect': (
        'base model under-fitted: re-fitting it alone shrinks the validation gap 12.0 +- 2.5 %; beyond '
        'that, input_delay (lat input delay delay 80 +- 5 ms): gap shrinks 40.0 % on the validation '
        'flight'),
    'unsettled': (
        'base model under-fitted: re-fitting it alone shrinks the validation gap 12.0 +- 2.5 % and it is '
        'still converging (training RSS down 3.2 % over the last 60 steps): re-identify the base model '
        "(jaxheli identify --method pem --data FILE, or the diagnosis's re-fitted base, refit.theta), or "
        'raise max_steps (--max-steps), before attributing effects'),
    'unsettled_not_under': (
        'base model under-fitted: re-fitting it alone shrinks the validation gap 12.0 +- 2.5 % and it is '
        'still converging (training RSS down 3.2 % over the last 60 steps): re-identify the base model '
        "(jaxheli identify --method pem --data FILE, or the diagnosis's re-fitted base, refit.theta), or "
        'raise max_steps (--max-steps), before attributing effects'),
    'structure_then_effect': (
        'base model under-fitted: re-fitting it alone shrinks the validation gap 12.0 +- 2.5 %; beyond '
        'that, base model structure: Nw freed (2.5), Xu beyond its bound (-3 past -1): re-fitting it in '
        'the physical ranges shrinks the validation gap 45.0 +- 5.0 %; beyond that, input_delay (lat '
        'input delay delay 80 +- 5 ms): gap shrinks 21.5 % on the validation flight'),
    'effect_beyond_structure': (
        'input_delay (lat input delay delay 80 +- 5 ms): gap shrinks 40.0 % on the validation flight, '
        "more than the base model's structure (Nw freed (2.5), Xu beyond its bound (-3 past -1): 30.0 +- "
        '5.0 %)'),
    'structure_only': (
        'base model structure: Nw freed (2.5), Xu beyond its bound (-3 past -1): re-fitting it in the '
        'physical ranges shrinks the validation gap 45.0 +- 5.0 %; beyond that, no significant effect'),
    'idle_structure': (
        'input_delay (lat input delay delay 80 +- 5 ms): gap shrinks 40.0 % on the validation flight'),
}
"""Each case's verdict line as ``jaxheli.gap.ranking.verdict`` returned it before the verdict became a record (the
command line prints it unchanged)."""


@pytest.mark.parametrize("name", sorted(GOLDEN))
def test_the_command_line_words_the_verdict_as_before(name):
    assert verdict_line(find(*_cases()[name])) == GOLDEN[name]


def test_the_library_sentence_names_no_option_and_differs_only_while_the_base_converges():
    for name, case in _cases().items():
        v = find(*case)
        assert str(v) == sentence(v) and "--" not in str(v), name
        assert (str(v) == GOLDEN[name]) == v.settled, name
    assert str(find(*_cases()["unsettled"])).endswith("no effect is attributed until it settles")


def test_the_record_says_what_was_found():
    c = _cases()
    assert find(*c["nothing"]) == Verdict()
    tied = find(*c["effect_tied"])
    assert tied.effect.effect == "input_delay" and tied.tied_with == ("actuator_lag",) and tied.structure is None
    assert tied.effect.shrink_pct == pytest.approx(40.0, abs=0.05) and tied.effect.fitted.params["delay_lat"].stderr == 0.005
    assert find(*c["effect_settled_refit"]).under_fitted is None  # settled and not under-fitted: not named
    under = find(*c["under_fitted_then_effect"])
    assert under.under_fitted is c["under_fitted_then_effect"][1] and under.settled
    for name in ("unsettled", "unsettled_not_under"):
        v = find(*c[name])
        assert not v.settled and v.effect is None and v.structure is None, name
    first = find(*c["structure_then_effect"])
    assert first.structure is c["structure_then_effect"][2] and first.outshrinks is None
    assert first.effect is c["structure_then_effect"][3][0]  # its entry of the re-check beyond the structure
    beyond = find(*c["effect_beyond_structure"])
    assert beyond.structure is None and beyond.outshrinks is c["effect_beyond_structure"][2]
    assert find(*c["structure_only"]).effect is None and find(*c["idle_structure"]).structure is None
    ranked, refit, structure, _ = c["structure_then_effect"]
    again = (dataclasses.replace(ranked[1], shrink_pct=30.0), dataclasses.replace(ranked[0], shrink_pct=21.5))
    assert find(ranked, refit, structure, again).effect is again[0]  # the one that explains most beyond it


_OPTION = re.compile(r"(?<![\\w-])--[a-z][a-z-]+")


def test_the_final_fit_and_the_blind_check_take_the_effect_the_verdict_names():
    """Beyond a named structure the verdict names the re-check's best (here the lag), not the box's (the delay): the
    entry whose size is re-identified, and which the blind check grades, is the box ranking's entry of the lag."""
    ranked = _entries()
    recheck = (dataclasses.replace(ranked[1], shrink_pct=30.0), dataclasses.replace(ranked[0], shrink_pct=20.0))
    verdict = find(ranked, None, _structure(45.0), recheck)
    assert verdict.structure is not None and named(ranked).effect == "input_delay"
    assert verdict.effect.effect == "actuator_lag" and named_entry(verdict, ranked) is ranked[1]
    assert named_entry(find(ranked), ranked) is ranked[0]
    unsettled = find(ranked, _refit(settled=False))
    assert unsettled.effect is None and named_entry(unsettled, ranked) is None


def test_a_blind_record_graded_again_gives_the_verdict_of_its_fits():
    """A blind trial's record keeps its fits without their base parameters; graded again, it names what the verdict
    of those fits names."""
    ranked, refit, structure = _entries(), _refit(), _structure(45.0)
    recheck = (dataclasses.replace(ranked[1], shrink_pct=30.0), dataclasses.replace(ranked[0], shrink_pct=20.0))

    def kept(r):
        return {k: v for k, v in r.to_json().items() if k != "theta"}

    record = {"ranking": [kept(e) for e in ranked], "base_refit": kept(refit), "structure": kept(structure),
              "recheck": [kept(e) for e in recheck], "beyond_noise": [], "noise_beyond": {}}
    verdict = find(ranked, refit, structure, recheck)
    assert regraded_top(record) == verdict.effect.effect == "actuator_lag"
    assert sentence(regrade(record)) == sentence(verdict)
    quiet = [kept(dataclasses.replace(e, significant=False, tied_with=())) for e in ranked]
    assert regraded_top({**record, "ranking": quiet}) == "none"


def test_a_servo_tied_with_a_delay_names_the_delay():
    """Within the noise the fewer parameters are named: a servo ranked first but tied with an input delay gives way
    to the delay, in the box and beyond a named structure; a servo tied with another effect, or alone, stays."""
    lag, delay, saturation = _entries((0.62, 0.6, 0.97))  # the lag's shrink (40 %) now leads the delay's (38 %)
    assert (lag.effect, delay.effect) == ("actuator_lag", "input_delay")
    ranking = [dataclasses.replace(lag, tied_with=("input_delay",)),
               dataclasses.replace(delay, tied_with=("actuator_lag",)), saturation]
    tied = find(ranking)
    assert tied.effect is ranking[1] and tied.tied_with == ("actuator_lag",)
    assert named_entry(tied, ranking) is ranking[1]
    recheck = tuple(ranking[:2])
    assert find(ranking, None, _structure(45.0), recheck).effect is recheck[1]
    alone = [dataclasses.replace(ranking[0], tied_with=("control_saturation",)), *ranking[1:]]
    assert find(alone).effect is alone[0]


def test_no_module_of_the_gap_package_words_a_command_line_option():
    """Strings in code under ``jaxheli/gap/`` (docstrings aside) name no ``--option``: the command line words
    its own advice."""
    found = []
    for path in sorted(GAP.rglob("*.py")):
        tree = ast.parse(path.read_text())
        docs = {id(n.body[0].value) for n in ast.walk(tree)
                if isinstance(n, (ast.Module, ast.FunctionDef, ast.ClassDef)) and n.body
                and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
                found += [f"{path.name}:{node.lineno}: {m}" for m in _OPTION.findall(node.value)]
    assert not found, found


@pytest.mark.parametrize("recheck, leads", [("significant", 30.0), ("all", 30.0), ("significant", 50.0), ("all", 50.0)])
def test_the_staged_ranking_re_checks_beyond_the_structure_what_its_rule_names(monkeypatch, recheck, leads):
    """Beyond a significant structure (45 %): a delay significant in the box but not beyond it is dropped; a lag not
    significant in the box but significant beyond it is ranked again and named only when every candidate is
    re-checked (``"all"``); a saturation significant in both stays named. A saturation that shrinks the gap further
    than the structure (``leads`` 50 %) is kept without a re-check, and then, under ``"all"``, the box's ranking
    stands (the structure is not the leading hypothesis)."""
    from jaxheli.gap import ranking
    from jaxheli.gap.candidates import Ranked

    delay, lag, saturation = _entries()
    box = [dataclasses.replace(delay, shrink_pct=10.0), dataclasses.replace(lag, shrink_pct=3.0, significant=False),
           dataclasses.replace(saturation, shrink_pct=leads)]
    box.sort(key=lambda e: -e.shrink_pct)  # best first, as a ranking is
    beyond = {"input_delay": dataclasses.replace(delay, significant=False), "actuator_lag": lag,
              "control_saturation": saturation}
    asked = []

    def fake_ranked(train, validate, theta, labels, arrays, owner, max_steps, min_shrink, box_):
        if theta == "beyond":
            asked.append(list(labels))
            assert [len(a) for a in arrays] == [len(owner)] * 4 and sorted(set(owner)) == list(range(len(labels)))
            return Ranked([beyond[name] for name in labels], None, None, None, None)
        return Ranked(box, None, None, None, None)

    monkeypatch.setattr(ranking, "ranked", fake_ranked)
    structure = dataclasses.replace(_structure(45.0), theta="beyond")
    monkeypatch.setattr(ranking, "structure_hypothesis", lambda *a: structure)
    monkeypatch.setattr(ranking, "theta_box", lambda theta, box_: box_)
    monkeypatch.setattr(ranking, "RECHECK", recheck)
    arrays = tuple(np.arange(6)[:, None] for _ in range(4))
    found = ranking.staged(None, None, "box", ["input_delay", "actuator_lag", "control_saturation"], arrays,
                           np.array([0, 0, 1, 1, 2, 2]), 15, 5.0, Bounds())
    named = {e.effect for e in found.ranked.entries if e.significant}
    expected = {("significant", 30.0): (["input_delay", "control_saturation"], {"control_saturation"}),
                ("all", 30.0): (["input_delay", "actuator_lag", "control_saturation"],
                                {"actuator_lag", "control_saturation"}),
                ("significant", 50.0): (["input_delay"], {"control_saturation"}),
                ("all", 50.0): (None, {"input_delay", "control_saturation"})}[recheck, leads]
    assert (asked or [None]) == [expected[0]] and named == expected[1]
    assert [e.effect for e in found.recheck] == (expected[0] or [])


def _noise_first(beyond_significant: bool):
    """A ranking led by process noise (gusts of 0.4 m/s, 2 s), a delay and a lag behind it, and their entries
    ranked again beyond the noise: the delay significant there or not."""
    from jaxheli.effects import registry as fx

    delay, lag, _ = _entries()
    noise = dataclasses.replace(delay, effect="process_noise", shrink_pct=45.0,
                                fitted=fx.report("process_noise", OUT, np.array([0.4, 2.0, 1.0]), np.full(3, 0.05)))
    beyond = (dataclasses.replace(delay, shrink_pct=12.0, significant=beyond_significant, tied_with=()),
              dataclasses.replace(lag, shrink_pct=4.0, significant=False, tied_with=()))
    return [noise, delay, lag], beyond


@pytest.mark.parametrize("beyond_significant", [True, False])
def test_process_noise_gives_way_to_an_effect_that_shrinks_the_gap_beyond_it(beyond_significant):
    """Process noise leads the ranking: a delay significant beyond it (its gusts freed in every fit) is named in its
    place, with its shrink beyond the noise and the noise named after it; with nothing significant beyond it, or
    only at a training likelihood ratio weaker than the threshold's p of 1e-8, the noise itself is named."""
    from jaxheli.gap.verdict import named

    ranking, beyond = _noise_first(beyond_significant)
    v = find(ranking, None, None, (), beyond)
    if beyond_significant:
        assert v.effect is beyond[0] and v.noise is ranking[0] and named(ranking, beyond) is ranking[1]
        assert str(v) == ("input_delay (lat input delay delay 80 +- 5 ms): gap shrinks 12.0 % on the validation "
                          "flight beyond process noise (u,v,w process noise gust_std 0.4 +- 0.05 m/s; u,v,w process "
                          "noise gust 2000 +- 50 ms; u,v,w process noise state_noise_cut 1 +- 0.05 ln)")
    else:
        assert v.effect is ranking[0] and v.noise is None and named(ranking, beyond) is ranking[0]
        assert str(v).startswith("process_noise (")
    assert find(ranking[1:], None, None, (), beyond).effect is ranking[1]  # noise not first: nothing changes
    weak = (dataclasses.replace(beyond[0], lr=dataclasses.replace(beyond[0].lr, p_value=1e-4)),) + beyond[1:]
    assert beyond[0].lr.p_value <= 1e-8 and find(ranking, None, None, (), weak).effect is ranking[0]


def test_the_staged_ranking_re_checks_beyond_process_noise_when_it_leads(monkeypatch):
    """When process noise is the box's best significant effect, the other candidates the restart filter does not
    read (not the bias's walk) are ranked again with its fitted gusts carried in every row, from its base
    parameters; when none is significant there, the noise is ranked beyond the bias significant in the box, from
    the bias's fit; otherwise no such ranking is made."""
    from jaxheli.gap import noise_last, ranking
    from jaxheli.gap.candidates import Ranked

    (noise, delay, lag), beyond = _noise_first(True)
    noise = dataclasses.replace(noise, theta="noise")
    bias = dataclasses.replace(delay, effect="output_bias_drift", shrink_pct=30.0, theta="bias")
    labels = ["input_delay", "process_noise", "output_bias_drift", "actuator_lag"]
    asked, answer = [], {}

    def fake_ranked(train, validate, theta, labels_, arrays, owner, max_steps, min_shrink, box_, carried=None):
        if carried is not None:
            asked.append((list(labels_), theta, carried))
            assert [len(a) for a in arrays] == [len(owner)] * 4 and sorted(set(owner)) == list(range(len(labels_)))
            return Ranked(answer[carried.effect], None, None, None, None)
        return Ranked(first, None, None, None, None)

    monkeypatch.setattr(ranking, "ranked", fake_ranked)
    monkeypatch.setattr(noise_last, "ranked", fake_ranked)
    monkeypatch.setattr(ranking, "structure_hypothesis", lambda *a: None)
    monkeypatch.setattr(ranking, "theta_box", lambda theta, box_: box_)
    monkeypatch.setattr(noise_last, "theta_box", lambda theta, box_: box_)
    arrays = tuple(np.arange(8)[:, None] for _ in range(4))
    quiet = [dataclasses.replace(e, significant=False) for e in beyond]
    after = dataclasses.replace(noise, shrink_pct=2.0, significant=False)
    past_noise = (["input_delay", "actuator_lag"], "noise", noise)
    for first, answer["process_noise"], expected, name in (
            ([noise, delay, lag], list(beyond), [past_noise], "input_delay"),
            ([noise, bias, delay, lag], list(beyond), [past_noise], "input_delay"),
            ([noise, bias, lag], quiet, [past_noise, (["process_noise"], "bias", bias)], "output_bias_drift"),
            ([noise, lag], quiet, [past_noise], "process_noise"),
            ([delay, noise, lag], list(beyond), [], "input_delay")):
        asked.clear()
        answer["output_bias_drift"] = [after]
        found = ranking.staged(None, None, "box", labels, arrays, np.repeat(np.arange(4), 2), 15, 5.0, Bounds())
        assert asked == expected
        assert found.beyond_noise == (tuple(answer["process_noise"]) if expected else ())
        assert dict(found.noise_beyond) == ({"output_bias_drift": after} if len(expected) > 1 else {})
        assert named(first, found.beyond_noise, found.noise_beyond).effect == name


def test_process_noise_gives_way_to_a_bias_it_adds_nothing_beyond():
    """Nothing the filter does not read is significant beyond the noise: a bias walk significant in the box that the
    noise adds nothing significant beyond is named in its place, with the noise's shrink beyond it; where the noise
    is significant beyond the bias, the noise is named."""
    ranking, beyond = _noise_first(False)
    bias = dataclasses.replace(ranking[1], effect="output_bias_drift", shrink_pct=40.0)
    ranking = [ranking[0], bias, ranking[2]]
    after = dataclasses.replace(ranking[0], shrink_pct=2.0, shrink_se_pct=1.5, significant=False)
    v = find(ranking, None, None, (), beyond, {"output_bias_drift": after})
    assert v.effect is bias and v.noise is ranking[0] and v.noise_after is after
    assert str(v).endswith("gap shrinks 40.0 % on the validation flight; process noise adds 2.0 +- 1.5 % beyond "
                           "it, not significant")
    v = find(ranking, None, None, (), beyond, {"output_bias_drift": dataclasses.replace(after, significant=True)})
    assert v.effect is ranking[0] and v.noise is None and v.noise_after is None


def test_carried_effect_parameters_come_before_the_nuisance_ones():
    """The columns every row frees: the carried effect's own parameters (started at its fitted values), then the
    nuisance parameters, last, where a fit's nuisance values are read back (:func:`fitted_nuisance`)."""
    from jaxheli.effects import registry as fx
    from jaxheli.gap.fit_effect import fitted_nuisance

    plain = fx.nuisance_arrays(OUT)
    slot, start, lower, upper = fx.nuisance_arrays(OUT, "process_noise", {"gust_std": 0.4, "gust_tau": 2.5})
    own = [p for p in fx.params("process_noise", OUT) if not p.nuisance]
    assert list(slot) == [p.slot for p in own] + list(plain[0])
    assert list(start[:2]) == [0.4, 2.5] and np.array_equal(start[2:], plain[1])
    assert np.array_equal(upper[2:], plain[3]) and list(upper[:2]) == [p.bound for p in own]
    assert fitted_nuisance(np.r_[0.0, 0.4, 2.5, plain[1]], OUT) == fitted_nuisance(np.r_[plain[1]], OUT)
