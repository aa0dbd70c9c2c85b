"""Unmodelled effects: one record per candidate effect (:mod:`~jaxheli.effects.record`, the library's eight in
:mod:`~jaxheli.effects.catalogue`), the names, units and ranges the diagnosis reports
(:mod:`~jaxheli.effects.registry`), and the effect-augmented plant that both flies synthetic truths and
predicts in the gap diagnosis (:mod:`~jaxheli.effects.plant`)."""
