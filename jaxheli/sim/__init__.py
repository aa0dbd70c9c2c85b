"""Simulation of the hover model on a flight: exact ZOH/FOH discretisation, the scan and blocked
(Gram-matrix) simulators, the parallel-in-time form of their recursions and the choice between forms, population
scoring sharded over local devices, and initial-state estimation."""
