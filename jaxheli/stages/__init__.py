"""Stages of an identification (:func:`jaxheli.identify` runs a chain of them), each an immutable module of its own
options, and the named methods as chains (:data:`CHAINS`, :data:`KEYWORDS`)."""

from ._frequency import FrequencyFit as FrequencyFit
from ._methods import (CHAINS as CHAINS, KEYWORDS as KEYWORDS, METHODS as METHODS, method_chain as method_chain,
                       used_by as used_by, uses as uses)
from ._pem import PEM as PEM
from ._polish import Polish as Polish
from ._prior import PRIOR_SD as PRIOR_SD, PriorModel as PriorModel
from ._search import Search as Search
from ._stage import Record as Record, Stage as Stage, Starts as Starts, Task as Task, check_chain as check_chain
from ._structure import Structure as Structure
