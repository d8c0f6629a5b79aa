"""Layer 1: the values every layer shares (constants and tuning defaults, errors, erf, geometry,
grids, time and path axes, histogram layouts, memory limits). Imports only NumPy."""
