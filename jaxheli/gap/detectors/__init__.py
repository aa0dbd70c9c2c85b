"""The data-consistency detectors of :func:`jaxheli.gap.consistency.check`, one stage per module: kinematics,
velocity frame and attitude bias, velocity lags, velocity travel; :mod:`.signals` holds what they share."""
