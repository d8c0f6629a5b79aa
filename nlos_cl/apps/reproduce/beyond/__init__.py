"""`nlos-cl reproduce beyond`: the paper's argmax against the model-based estimator where the
paper stops. The experiment (experiment.beyond) and its sections; the cases (cases, from
beyond.yaml); one frame's run (runs: the sweep engine's runner) and the study around them
(sweep); the page (report, its prose in text.yaml)."""
from .experiment import beyond

__all__ = ["beyond"]
