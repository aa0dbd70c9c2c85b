"""jaxheli: JAX-accelerated, differentiable system identification of small unmanned helicopters.

Mettler's 13-state hover model (:mod:`jaxheli.model`), a batched ZOH/FOH simulator
(:mod:`jaxheli.sim.simulate`), the paper's Pearson cost and amplitude metrics (:mod:`jaxheli.cost`),
flight-data readers (:mod:`jaxheli.io`), piloted synthetic flights (:mod:`jaxheli.synth`), and the
identification engines (:mod:`jaxheli.optim`, :func:`jaxheli.identify`).
"""

from ._xla import configure_xla as configure_xla
from .cost import fit_percent as fit_percent, metrics as metrics, paper_cost as paper_cost
from .cost import nmse as nmse, output_error_cost as output_error_cost
from .cost import pearson as pearson, rmse as rmse, tic as tic
from . import distributed as distributed, gap as gap
from .sim.discretize import Discrete as Discrete, discretize as discretize
from .evaluate import evaluate as evaluate, resolve_params as resolve_params, simulate_as_scored as simulate_as_scored
from .synth.excitation import Excitation as Excitation, doublet as doublet, multisine as multisine
from .synth.excitation import sweep as sweep, three_two_one_one as three_two_one_one
from .data.flight import FlightData as FlightData, FlightDataError as FlightDataError
from .identify import IdentificationResult as IdentificationResult, identify as identify
from .sim.initial_state import Start as Start, estimate_start as estimate_start, estimate_x0 as estimate_x0
from .at_bounds import AtBound as AtBound, at_bounds as at_bounds
from .modes import Mode as Mode, modes as modes
from .io import DEFAULT_PX4 as DEFAULT_PX4, DEFAULT_ULOG as DEFAULT_ULOG, load as load, load_ulog as load_ulog
from .io import save_csv as save_csv, save_npz as save_npz
from .data.plausible import check_plausible as check_plausible
from .gap.prepare import prepare as prepare
from .gap.records import Diagnosis as Diagnosis, Entry as Entry
from .model import (
    G_SI as G_SI,
    INPUT_NAMES as INPUT_NAMES,
    LOWER as LOWER,
    MEASURABLE as MEASURABLE,
    PARAM_NAMES as PARAM_NAMES,
    PINNED as PINNED,
    R50_G as R50_G,
    R50_HOVER as R50_HOVER,
    R50_SI as R50_SI,
    STATE_NAMES as STATE_NAMES,
    TABLE2 as TABLE2,
    UPPER as UPPER,
    build_ab as build_ab,
    feet_to_si as feet_to_si,
    output_matrix as output_matrix,
    params_array as params_array,
    params_dict as params_dict,
)
from .optim import GA as GA, IWO as IWO, minimize as minimize, minimize_trials as minimize_trials
from .distributed import minimize_trials_distributed as minimize_trials_distributed
from .optim import pem as pem, polish as polish, standard_errors as standard_errors
from .optim import Prior as Prior, determine_structure as determine_structure
from .optim import CrossValidation as CrossValidation, cross_validate as cross_validate
from .optim import cramer_rao_coverage as cramer_rao_coverage, output_error as output_error
from .sim.population import PopulationCost as PopulationCost, population_cost as population_cost
from .bounds import Bounds as Bounds
from .problem import Problem as Problem, Records as Records, Settings as Settings, make_problem as make_problem
from .problem import make_records as make_records
from .data.preprocess import detrend as detrend, from_samples as from_samples, lowpass as lowpass
from .data.preprocess import resample as resample, split as split, trim as trim
from .report import build_report as build_report, write_report as write_report
from ._progress import reporting as reporting
from ._compile_cache import use_compile_cache as use_compile_cache
from .results import save_result as save_result
from .verify import Verification as Verification, save_verification as save_verification, verify as verify
from .sim.simulate import Simulator as Simulator, make_simulator as make_simulator, simulate as simulate
from .synth.piloted import Pilot as Pilot, default_flight as default_flight, piloted_flight as piloted_flight

__version__ = "0.1.0"
