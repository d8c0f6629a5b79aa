"""What to fit and which fit to keep: starts, model selection, closed shapes, subsets of
detectors, the filtered search, warm starts, depth and sanity checks. Imports solve,
forward and shapes."""
