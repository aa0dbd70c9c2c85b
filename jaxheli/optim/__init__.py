"""Optimisers of the hover-model parameters: metaheuristics, prediction-error minimisation, polishing."""
