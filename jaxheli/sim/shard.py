"""Spread a population over the local devices, one shard per device, when there is more than one.

Candidates are independent, so the population axis splits without communication (``shard_map``); each
device runs the same program on its slice. On CPU, ``XLA_FLAGS=--xla_force_host_platform_device_count=2``
(set before JAX starts) gives two host devices, which lets the sequential parts of the kernel run on
both cores at once. Only kernels free of LAPACK calls may run this way on CPU: LAPACK's batched
routines wait on the shared thread pool and deadlock when two host devices run them together.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, PartitionSpec

from .._types import Array

AXIS = "population"
MIN_PER_DEVICE = 32
"""Smaller shards are not worth the extra dispatch; below ``MIN_PER_DEVICE`` per device one device runs."""


def map_population(fn: Callable[..., Array], thetas: Array, *shared, shard: bool | None = None) -> Array:
    """``fn(thetas, *shared)`` with the leading (population) axis of ``thetas`` and of the result split over
    the local devices; ``shared`` (pytrees of arrays) go to every device whole.

    ``shard=None`` shards when there are several local devices and at least :data:`MIN_PER_DEVICE`
    candidates per device; ``True`` / ``False`` force it. The population is padded (with copies of its
    first candidate) to a multiple of the device count and the padding dropped from the result.
    """
    devices = jax.local_devices()
    count = len(devices)
    size = thetas.shape[0]
    if shard is None:
        shard = count > 1 and size >= MIN_PER_DEVICE * count
    if not shard or count == 1:
        return fn(thetas, *shared)
    pad = (-size) % count
    if pad:
        thetas = jnp.concatenate([thetas, jnp.broadcast_to(thetas[:1], (pad,) + thetas.shape[1:])])
    mesh = Mesh(np.array(devices), (AXIS,))
    spec = PartitionSpec(AXIS)
    run = jax.shard_map(
        fn, mesh=mesh, in_specs=(spec,) + (PartitionSpec(),) * len(shared), out_specs=spec, check_vma=False
    )
    return run(thetas, *shared)[:size]
