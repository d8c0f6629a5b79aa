"""Solvers: Levenberg-Marquardt (lm), fits of one or many targets (fit, lockstep), width
vectors and covariances. Imports forward and shapes."""
