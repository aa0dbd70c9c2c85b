"""Blind check of the effect diagnosis on piloted synthetic flights with one withheld effect (or none).

Each trial draws a scenario (:func:`scenario`: truth model, pilot/excitation style, sensor-noise level,
effect strength) and one effect kind at a random realistic magnitude (:func:`sample_injection`), flies a
training and a held-out validation flight of the truth plant carrying it (different excitations,
independent noise) and diagnoses them without being told which. The base model is what a user would have:
identified on the contaminated training flight (never the truth), in one box that covers both helicopter
classes (:data:`BOX`): by PEM, or by IWO and its gradient polish (:data:`BASES`, :func:`base_model`). The
diagnosis is the library's default: every candidate fitted jointly with the base parameters, credited beyond
the base re-fitted alone (:func:`~jaxheli.gap.ranking.fit_and_score`) or the given base, whichever predicts the
validation flight better (:func:`~jaxheli.gap.significance.yardstick`).
The oracle is the identified base with the *true* effect, started at its true values and fitted jointly the
same way; its own magnitude error shows how much of the diagnosis's is the identified base's. The named
effect's size is then re-identified on both flights (:func:`~jaxheli.gap.final_fit.final_fit`). All trials of
a run share the flight length, so each fit compiles once; candidates are fitted in one compiled solve, mapped
over them.

Modules, one job each: :mod:`._scenario` (truth, pilot style, noise, strength per seed; the boxes),
:mod:`._injection` (the library simulator's withheld effect), :mod:`._flights` (either simulator's flights and the
noise-free pairs that decide detectability), :mod:`._base` (the base model), :mod:`._trial` (one trial and its
record), :mod:`._pool` (trials in processes pinned to cores), :mod:`._regrade` (a record graded again by the current
rules), :mod:`._summary` and :mod:`._markdown` (statistics and tables), :mod:`._run` (a run on the protocol's
seeds, recorded in the seed ledger, :mod:`jaxheli.gap.ledger`) and :mod:`._resume` (a stopped run resumed).
"""

from ._base import BASES as BASES, base_model as base_model
from ._flights import TRUTHS_SIM as TRUTHS_SIM, blind_flights as blind_flights, noise_free_pair as noise_free_pair
from ._flights import trial_flights as trial_flights
from ._injection import KINDS as KINDS, Injection as Injection, sample_injection as sample_injection
from ._markdown import markdown as markdown
from ._pool import run_blind as run_blind
from ._regrade import regrade as regrade, regraded_top as regraded_top
from ._resume import resume_benchmark as resume_benchmark
from ._run import run_benchmark as run_benchmark
from ._scenario import BOX as BOX, BOXES as BOXES, NOISES as NOISES, STRENGTHS as STRENGTHS, STYLES as STYLES
from ._scenario import TRUTHS as TRUTHS, VALIDATE_EXCITATION as VALIDATE_EXCITATION, Scenario as Scenario
from ._scenario import TRUTH_CLASSES as TRUTH_CLASSES, scenario as scenario
from ._summary import detectable as detectable, forms as forms, explainable as explainable, identifiable as identifiable
from ._summary import beyond_structure as beyond_structure
from ._summary import explainable_beyond_structure as explainable_beyond_structure
from ._summary import resolvable as resolvable, summarise as summarise, summarise_bases as summarise_bases
from ._summary import summarise_records as summarise_records, wilson_interval as wilson_interval
from ._trial import Trial as Trial, run_trial as run_trial
