"""jaxheli: JAX-accelerated, differentiable system identification of small unmanned helicopters.

Mettler's 13-state hover model (:mod:`jaxheli.model`), a batched ZOH/FOH simulator
(:mod:`jaxheli.sim.simulate`), the paper's Pearson cost and amplitude metrics (:mod:`jaxheli.cost`),
flight-data readers (:mod:`jaxheli.io`), piloted synthetic flights (:mod:`jaxheli.synth`), the
identification engines (:mod:`jaxheli.optim`, :func:`jaxheli.identify`) and the sim-to-real gap diagnosis
(:mod:`jaxheli.gap`).

The names below are the API; everything else stays in its module (for example ``jaxheli.io.load_ulog``,
``jaxheli.model.R50_SI``, ``jaxheli.optim.cross_validate``, ``jaxheli.distributed``). Importing jaxheli changes
no environment variable: call :func:`configure_xla` before JAX's first computation when the diagnosis runs on the
CPU (the ``jaxheli`` command does).

- flight files: ``load``, ``save_csv``, ``save_npz``, ``check_plausible``
- flight data and preprocessing: ``FlightData``, ``FlightDataError``, ``from_samples``, ``trim``, ``split``,
  ``resample``, ``lowpass``, ``detrend``
- the model: ``TABLE2``, ``PARAM_NAMES``, ``STATE_NAMES``, ``INPUT_NAMES``, ``MEASURABLE``, ``LOWER``, ``UPPER``,
  ``build_ab``, ``params_array``, ``params_dict``
- problems: ``Settings``, ``Bounds``, ``Problem``, ``Records``, ``make_problem``, ``make_records``
- simulation and cost: ``simulate``, ``make_simulator``, ``Simulator``, ``estimate_x0``, ``population_cost``,
  ``evaluate``, ``metrics``, ``pearson``, ``paper_cost``, ``output_error_cost``, ``rmse``, ``tic``,
  ``fit_percent``, ``nmse``
- identification: ``identify``, ``IdentificationResult``, ``save_result``, ``IWO``, ``GA``, ``minimize``,
  ``minimize_trials``, ``pem``, ``polish``, ``standard_errors``, and the stages ``identify`` chains: ``stages``
- checking a model: ``verify``, ``Verification``, ``save_verification``, ``modes``, ``Mode``
- the gap diagnosis: ``gap``
- the report: ``build_report``, ``write_report``
- synthetic flights: ``piloted_flight``, ``default_flight``, ``Pilot``, ``Excitation``, ``doublet``,
  ``three_two_one_one``, ``sweep``, ``multisine``
- setup: ``configure_xla``
"""

from . import gap as gap, stages as stages
from ._xla import configure_xla as configure_xla
from .bounds import Bounds as Bounds
from .cost import fit_percent as fit_percent, metrics as metrics, nmse as nmse
from .cost import output_error_cost as output_error_cost, paper_cost as paper_cost
from .cost import pearson as pearson, rmse as rmse, tic as tic
from .data.flight import FlightData as FlightData, FlightDataError as FlightDataError
from .data.plausible import check_plausible as check_plausible
from .data.preprocess import detrend as detrend, from_samples as from_samples, lowpass as lowpass
from .data.preprocess import resample as resample, split as split, trim as trim
from .evaluate import evaluate as evaluate
from .identify import IdentificationResult as IdentificationResult, identify as identify
from .io import load as load, save_csv as save_csv, save_npz as save_npz
from .model import INPUT_NAMES as INPUT_NAMES, LOWER as LOWER, MEASURABLE as MEASURABLE
from .model import PARAM_NAMES as PARAM_NAMES, STATE_NAMES as STATE_NAMES, TABLE2 as TABLE2, UPPER as UPPER
from .model import build_ab as build_ab, params_array as params_array, params_dict as params_dict
from .modes import Mode as Mode, modes as modes
from .optim import GA as GA, IWO as IWO, minimize as minimize, minimize_trials as minimize_trials
from .optim import pem as pem, polish as polish, standard_errors as standard_errors
from .problem import Problem as Problem, Records as Records, Settings as Settings
from .problem import make_problem as make_problem, make_records as make_records
from .report import build_report as build_report, write_report as write_report
from .results import save_result as save_result
from .sim.initial_state import estimate_x0 as estimate_x0
from .sim.population import population_cost as population_cost
from .sim.simulate import Simulator as Simulator, make_simulator as make_simulator, simulate as simulate
from .synth.excitation import Excitation as Excitation, doublet as doublet, multisine as multisine
from .synth.excitation import sweep as sweep, three_two_one_one as three_two_one_one
from .synth.piloted import Pilot as Pilot, default_flight as default_flight, piloted_flight as piloted_flight
from .verify import Verification as Verification, save_verification as save_verification, verify as verify

__version__ = "0.1.0"
