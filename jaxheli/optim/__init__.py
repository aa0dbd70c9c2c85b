"""Identification engines: IWO and GA (ask/tell population optimisers), PEM and gradient polish
(optimistix least squares), the run driver (chunked scan, checkpoints, vmapped trials), uncertainty, a Gaussian
prior of the local fits, the model-structure determination and the polish's cross-validation."""

from ._base import AbstractPopulationOptimizer as AbstractPopulationOptimizer, Candidates as Candidates
from .cross_validate import CrossValidation as CrossValidation, cross_validate as cross_validate
from .ga import GA as GA, GAState as GAState
from .iwo import IWO as IWO, IWOState as IWOState
from .output_error import output_error as output_error, output_error_problem as output_error_problem
from .output_error import restart_interval as restart_interval
from .pem import PEMResult as PEMResult, pem as pem
from .polish import polish as polish
from .prior import Prior as Prior
from .run import RunResult as RunResult, minimize as minimize, minimize_trials as minimize_trials
from .uncertainty import Identifiability as Identifiability, Uncertainty as Uncertainty
from .uncertainty import cramer_rao_coverage as cramer_rao_coverage
from .uncertainty import from_residuals as from_residuals, identifiable as identifiable
from .uncertainty import standard_errors as standard_errors
from .structure import FixedParameter as FixedParameter, StructureResult as StructureResult
from .structure import determine_structure as determine_structure
