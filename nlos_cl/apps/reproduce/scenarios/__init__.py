"""`nlos-cl reproduce scenarios`: first-use scenes drawn at random, each run through the command
line with no option and scored against its truths. The experiment (experiment: scenarios,
rerun, write_doc); the draws (draws; a sequence's movers and furniture: sequences) and their
ranges (scenarios.yaml); a draw as files and geometry (scenes); one draw's run (run) and its
score (score); the tables (report)."""
from .experiment import rerun, scenarios, write_doc

__all__ = ["rerun", "scenarios", "write_doc"]
