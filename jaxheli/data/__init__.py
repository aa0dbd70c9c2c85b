"""Flight data in memory: :class:`FlightData` (time, sticks, measured outputs, units, provenance) and its
preprocessing (trim, detrend, low-pass, resample, split)."""

from .flight import FlightData as FlightData, FlightDataError as FlightDataError
