"""Performance measurements (``jaxheli bench``): throughput of the cost kernels over population size and
flight length, seconds per IWO generation, the paper's whole experiment end to end and scaling over local
devices, each next to the baselines a user would otherwise pick (a per-candidate NumPy loop, mealpy's IWO)
measured in the same run and reported as ratios."""
