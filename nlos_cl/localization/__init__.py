"""Layer 7: from histograms to positions: the Gauss filter and fit, background removal, the
search region, coarse-to-fine search, the Locator plan and the estimators (paper.py, model/)."""
