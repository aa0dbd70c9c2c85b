"""Synthetic flights: excitation signals (3-2-1-1, doublet, sweep, multisine) and piloted flights of a
known model, flown by a simulated pilot as a real flight is."""

from .excitation import Excitation as Excitation, doublet as doublet, multisine as multisine
from .excitation import sweep as sweep, three_two_one_one as three_two_one_one
from .piloted import DEFAULT_NOISE as DEFAULT_NOISE, DEFAULT_OUTPUTS as DEFAULT_OUTPUTS, Pilot as Pilot
from .piloted import default_flight as default_flight, piloted_flight as piloted_flight
