"""Unmodelled effects: the registry of candidate effects (parameters, units, physical ranges) and the
effect-augmented plant that both flies synthetic truths and predicts in the gap diagnosis."""
