"""Sim-to-real gap diagnosis: data consistency, where the model misses, which unmodelled effect, how far it shrinks.

The gap of a channel is its normalised residual energy, :func:`jaxheli.cost.nmse`.
"""
