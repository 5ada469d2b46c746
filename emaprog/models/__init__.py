"""Model runners: the boundary between scenarios/parameters and the kernels."""
