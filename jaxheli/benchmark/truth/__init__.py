"""An independent truth simulator for the blind check of the gap diagnosis (plain numpy/scipy).

Mettler's hover model rebuilt from ``DESIGN.md``, flown at a fine internal step by a pilot of its own, with effects
written the way the hardware and the air have them, in forms that no catalogue candidate reproduces within the sensor
noise but for the kinds of :data:`IN_FAMILY` (``tests/test_truth_forms.py``); only parameter names, reference
parameter vectors and the authors' box come from :mod:`jaxheli.model`. Truth hover models of a wider class than the
authors' box: :func:`wide_truth`. :func:`truth_trial` draws
a kind and flies a training and a validation flight, and decides detectability before any fit.
"""

from ._airframe import Drag as Drag, Governor as Governor
from ._class import COUPLINGS as COUPLINGS, outside_box as outside_box, wide_truth as wide_truth
from ._flight import NOISE as NOISE, OUTPUTS as OUTPUTS, Effects as Effects, Record as Record, fly as fly
from ._hover import STATES as STATES, STICKS as STICKS, gust_matrix as gust_matrix, hover_model as hover_model
from ._kinds import IN_FAMILY as IN_FAMILY, KIND_CANDIDATES as KIND_CANDIDATES, KINDS as KINDS, SINGLE as SINGLE
from ._kinds import Dice as Dice
from ._kinds import Injected as Injected, draw as draw, join as join
from ._pilot import excitation as excitation, lqr_gain as lqr_gain
from ._sensors import BiasDrift as BiasDrift, Imu as Imu, Quantiser as Quantiser, Vibration as Vibration, read as read
from ._servo import Servo as Servo, ServoState as ServoState
from ._trial import TruthTrial as TruthTrial, detectability as detectability, truth_trial as truth_trial
from ._trial import VALIDATE_STYLE as VALIDATE_STYLE, detectability_ratio as detectability_ratio
from ._turbulence import Dryden as Dryden
