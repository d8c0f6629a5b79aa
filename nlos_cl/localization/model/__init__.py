"""The model-based estimator (analysis by synthesis): fit parametric targets to the measured
histograms with the forward model, report centre, extent and a covariance per target.

    loc = nl.locate(filtered, grid, estimator="model", raw=noisy)
    loc = nl.locate(filtered, grid, estimator=ModelEstimator(targets="auto"), raw=noisy)

See docs/model-estimator.md. No SciPy on this path (a one-shot `nlos-cl locate` would pay
~0.5 s to import it): the least squares are nlos_cl.localization.model.solve.lm.
"""
from .estimator import HEIGHT_WARNING, ModelEstimator
from .options import FitBudget, Instrument
from .shapes.box import box_facets
from .shapes.plate import height_observable, plate_facets

__all__ = ["FitBudget", "HEIGHT_WARNING", "Instrument", "ModelEstimator", "box_facets",
           "height_observable", "plate_facets"]
