"""Sim-to-real gap diagnosis: data consistency, where the model misses, which unmodelled effect, how far it shrinks.

The gap of a channel is its normalised residual energy, :func:`jaxheli.cost.nmse`.
"""

from .consistency import Finding as Finding, check as check, correct as correct
from ..spectra import FrequencyResponse as FrequencyResponse, estimate_frequency_response as estimate_frequency_response
from ..spectra import mismatch as mismatch, model_frequency_response as model_frequency_response
from ..spectra import residual_frequency_response as residual_frequency_response
from .localise import localise as localise
from .localisation_record import Localisation as Localisation
from .compare import frequency_comparison as frequency_comparison, localise_model as localise_model
from .compare import localise_prediction as localise_prediction
from .diagnose import diagnose as diagnose, write_diagnosis as write_diagnosis
from .prepare import prepare as prepare
from .ranking import combine_effects as combine_effects, diagnose_effects as diagnose_effects
from .ranking import predictor_pair as predictor_pair, rank_effects as rank_effects
from .records import Attribution as Attribution, Diagnosis as Diagnosis, Entry as Entry, Final as Final
from .records import Refit as Refit, Structure as Structure
from .verdict import Verdict as Verdict
from .structure import physical_box as physical_box, structure_hypothesis as structure_hypothesis
