"""Simulation of the hover model on a flight: exact ZOH/FOH discretisation, the scan and blocked
(Gram-matrix) simulators, population scoring sharded over local devices, and initial-state estimation."""
