"""`nlos-cl reproduce draws`: the estimators on random draws (the draws themselves are
nlos_cl.simulation.draws). The experiment (experiment: draws, rerun, write_doc); one draw's run
(run; a crossing draw's tracked sequence: cross_run); the tables and targets from the rows
(report; cross_report for crossings)."""
from .experiment import draws, rerun, write_doc

__all__ = ["draws", "rerun", "write_doc"]
