"""The model-based estimator (analysis by synthesis): fit parametric targets to the measured
histograms with the forward model, report centre, extent and a covariance per target.

    loc = nl.locate(filtered, grid, estimator="model", raw=noisy)
    loc = nl.locate(filtered, grid, estimator=ModelEstimator(targets="auto"), raw=noisy)

See docs/model-estimator.md. SciPy is imported here (not at `import nlos_cl`).
"""
from .estimator import HEIGHT_WARNING, ModelEstimator, model_estimator
from .plate import height_observable, plate_facets

__all__ = ["HEIGHT_WARNING", "ModelEstimator", "height_observable", "model_estimator",
           "plate_facets"]
