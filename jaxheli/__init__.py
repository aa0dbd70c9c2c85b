"""jaxheli: JAX-accelerated, differentiable system identification of small unmanned helicopters."""
