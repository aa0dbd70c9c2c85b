"""The benchmarks the ``jaxheli`` command runs: ``bench`` (throughput of the cost kernels over population size and
flight length, seconds per IWO generation, the paper's experiment end to end, scaling over local devices, each next
to the baselines a user would otherwise pick, measured in the same run and reported as ratios), ``trials-scaling``
and ``blind`` (the blind check of the effect diagnosis, :mod:`.blind`, its independent truth simulator,
:mod:`.truth`; the ledger of spent seeds is :mod:`jaxheli.gap.ledger`).

Where benchmark code lives: code a ``jaxheli`` command runs lives here, in the package, because an installed
jaxheli ships the package and not the repository's ``benchmarks/`` folder; ``benchmarks/`` holds only runnable
scripts (thin wrappers of these commands, and studies that are no command) that import the package and write their
JSON and markdown. Nothing in the package imports from ``benchmarks/``.
"""
