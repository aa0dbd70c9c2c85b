"""Analytic test problems shared by the population-optimiser tests (known minima, bad-cost holes)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

SHIFT = jnp.array([1.3, -2.2, 0.7, 3.1, -0.4, 2.5])
LO6, HI6 = -5.0 * np.ones(6), 5.0 * np.ones(6)


def in_box(thetas, lower, upper):
    """Fail the run (inside jit) if any candidate handed to the cost leaves the box."""
    lo, hi = jnp.asarray(lower)[None, :], jnp.asarray(upper)[None, :]
    return eqx.error_if(thetas, jnp.any((thetas < lo) | (thetas > hi)), "candidate outside the bounds")


class Bowl(eqx.Module):
    """Shifted sphere on [-5, 5]^6; with ``holes``: NaN over the optimum (x0 > 1), +inf where x1 > 2,
    -inf where x2 < -3. The flag is an array, so both variants share one compiled run."""

    holes: jax.Array

    def __call__(self, thetas):
        thetas = in_box(thetas, LO6, HI6)
        cost = jnp.sum((thetas - SHIFT[None, :]) ** 2, axis=1)
        holey = jnp.where(thetas[:, 0] > 1.0, jnp.nan, cost)
        holey = jnp.where(thetas[:, 1] > 2.0, jnp.inf, holey)
        holey = jnp.where(thetas[:, 2] < -3.0, -jnp.inf, holey)
        return jnp.where(self.holes, holey, cost)


SPHERE, HOLEY = Bowl(jnp.asarray(False)), Bowl(jnp.asarray(True))


class Rosenbrock(eqx.Module):
    """Rosenbrock function, checked to stay inside ``[lower, upper]`` (pinned axes have lower == upper)."""

    lower: jax.Array = eqx.field(converter=jnp.asarray)
    upper: jax.Array = eqx.field(converter=jnp.asarray)

    def __call__(self, thetas):
        thetas = in_box(thetas, self.lower, self.upper)
        x, y = thetas[:, :-1], thetas[:, 1:]
        return jnp.sum(100.0 * (y - x**2) ** 2 + (1.0 - x) ** 2, axis=1)
