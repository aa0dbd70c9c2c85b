"""Array type aliases shared by the public signatures (jaxtyping shapes)."""

from jaxtyping import Array, ArrayLike, Bool, Float, Int

Params = Float[ArrayLike, "*batch 40"]
"""Parameter vector(s) in the order of :data:`jaxheli.PARAM_NAMES`."""

Population = Float[ArrayLike, "pop 40"]
"""A population of candidate parameter vectors."""

StateMatrix = Float[Array, "*batch 13 13"]
InputMatrix = Float[Array, "*batch 13 4"]
Inputs = Float[ArrayLike, "time 4"]
Outputs = Float[ArrayLike, "time channel"]

__all__ = [
    "Array",
    "ArrayLike",
    "Bool",
    "Float",
    "Int",
    "Params",
    "Population",
    "StateMatrix",
    "InputMatrix",
    "Inputs",
    "Outputs",
]
